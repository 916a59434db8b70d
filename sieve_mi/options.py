"""Command-line options made from settings tables: one option builder for every subcommand.

Each field of a settings dataclass (:mod:`sieve_mi.settings`) becomes one option with its flag,
help, metavar and default taken from the field's :class:`~sieve_mi.settings.Spec`
(:func:`add_options`); the values given are checked as a scene file's keys are
(:func:`check_options`, :func:`read_option`), so the command line and files refuse the same
values with the same line.
"""

from __future__ import annotations

from dataclasses import MISSING, fields

from sieve_mi.settings import describe, field_of, read_value, spec_of, value_types

__all__ = ["add_options", "check_options", "option_flag", "option_help", "read_option"]


def option_help(cls: type, f, default) -> str:
    """A command-line option's help from its field: meaning; accepted values (range, unit,
    default), with ``%`` escaped for argparse."""
    spec = spec_of(f)
    text = spec.doc + (f"; one of {', '.join(spec.choices)}" if spec.choices else "")
    shown = spec.default_doc if spec.default_doc is not None else default
    notes = [describe(cls, f)] if spec.minimum is not None or spec.maximum is not None else []
    notes += ([spec.unit] if spec.unit else []) + [f"default {shown}"]
    return f"{text} ({', '.join(notes)})".replace("%", "%%")


def option_flag(name: str) -> str:
    """The option of field ``name``: ``--`` and the name with dashes (``--fit-tolerance``)."""
    return "--" + name.replace("_", "-")


def add_options(parser, table: type, *names: str, flags: dict | None = None) -> None:
    """Add the options of fields ``names`` (default: every field) of a settings table.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        A command's parser.
    table : type
        A settings dataclass (:class:`~sieve_mi.game.check_settings.CheckSettings`, ...).
    names : str
        Its fields to add, in this order.
    flags : dict of str to str, optional
        An option's name where it is not :func:`option_flag` of the field's name.

    Notes
    -----
    Everything comes from the field: the default, the help (:func:`option_help`) and the
    metavar; a bool field that defaults to true is turned off by ``--no-NAME``. The value lands
    in ``args.<field name>`` as given; :func:`check_options` checks it as a scene file's key.
    """
    for name in names or [f.name for f in fields(table)]:
        f, kind = field_of(table, name), value_types(table)[name]
        spec, default = spec_of(f), (None if f.default is MISSING else f.default)
        flag = (flags or {}).get(name, option_flag(name))
        if kind is bool:
            off = default is True
            parser.add_argument(
                f"--no-{flag[2:]}" if off else flag,
                dest=name,
                action="store_false" if off else "store_true",
                help=f"turn {'off' if off else 'on'} {spec.doc}".replace("%", "%%"),
            )
        else:
            choices = "{" + ",".join(spec.choices) + "}" if spec.choices else None
            parser.add_argument(
                flag,
                dest=name,
                default=default,
                metavar=choices or flag[2:].upper().replace("-", "_"),
                help=option_help(table, f, default),
            )
        options = parser.get_default("setting_options") or ()
        parser.set_defaults(setting_options=(*options, (flag, table, name)))


def read_option(table: type, name: str, value, where: str, flag: str | None = None):
    """The value of field ``name`` of ``table`` given as option ``flag`` (default
    :func:`option_flag`) of command ``where``, checked by :func:`read_value`.

    Text of a number field is read as a whole number where it is one, else as a decimal number,
    as a scene file's ``3`` and ``3.0`` are; other text is kept, which :func:`read_value` then
    refuses in one line (``expected a number, got 'fast'``). A value that is not text is checked
    as it is.
    """
    if isinstance(value, str) and value_types(table)[name] in (int, float):
        for read in (int, float):
            try:
                value = read(value)
                break
            except ValueError:
                pass
    return read_value(table, name, value, where, flag or option_flag(name))


def check_options(args, where: str | None = None) -> None:
    """Check every option of ``args`` that :func:`add_options` added, as a scene file's keys
    are, and keep the value read (an int field's ``"7"`` becomes 7). The first bad value is one
    SieveError line naming the command (``where``, default ``args.command``) and the option.
    """
    for flag, table, name in getattr(args, "setting_options", ()):
        value = getattr(args, name)
        if value is not None:
            setattr(args, name, read_option(table, name, value, where or args.command, flag))
