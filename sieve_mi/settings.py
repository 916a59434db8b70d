"""Settings declared once: each a dataclass field with its default, bounds, unit and meaning.

A *settings table* is a dataclass whose fields are made by :func:`setting`: the field carries the
default, its :class:`Spec` carries the bounds or accepted values, the unit and the one-line
meaning. Everything else is derived from that one declaration:

* checking a value (:func:`read_value`, :class:`Reader`): one rule for a key of a file, a value
  given in code and a command-line option, with one :class:`~sieve_mi.errors.SieveError` line
  naming the place, e.g. ``check: --steps: must be >= 1, got -2``;
* checking in code (:func:`checked`, :func:`known_names`): a table that checks what it is made
  with and what is set on it, and refuses a name it does not have (:class:`UnknownSettingError`);
* documentation (:func:`documented`, :func:`describe`): the class docstring's ``Attributes`` and
  the type column of ``docs/scene-format.md``;
* command-line options (:func:`add_options`, :func:`check_options`): every subcommand builds its
  options (default, help, metavar) from the fields and checks them as a file's keys are.

The tables themselves live where they are used: the scene's in :mod:`sieve_mi.scene`,
``sieve-mi check``'s in :mod:`sieve_mi.game.check_settings`, the shaker's in
:mod:`sieve_mi.shake.settings`. Adding a setting is one line in its class, e.g.::

    certify: bool = setting(False, "prove the winner exactly")
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import re
import types
import typing
from dataclasses import MISSING, dataclass, field, fields

import numpy as np

from sieve_mi.errors import SieveError

__all__ = [
    "NAME_MAX",
    "check_folder_name",
    "check_name",
    "ANGLES",
    "ANGLES_MAX",
    "LENGTH_MAX",
    "SEED_MAX",
    "SIZE",
    "Reader",
    "Spec",
    "UnknownSettingError",
    "checked",
    "cut",
    "describe",
    "documented",
    "field_of",
    "key_of",
    "key_text",
    "known_names",
    "like",
    "read_value",
    "refuse_unknown",
    "setting",
    "shown",
    "spec_of",
    "value_types",
]

#: Largest length a scene accepts (scales, tolerances, margins, plate sizes): a kilometre in mm.
#: Beyond it the polygon offsets and rasters overflow; nothing real is that large.
LENGTH_MAX = 1_000_000
#: Largest seed (nlopt's generator takes an unsigned 64-bit seed).
SEED_MAX = 2**64 - 1
#: The value type of a setting that is a width and a height (``plate_size = [100, 100]``), each
#: checked against the setting's bounds; held as a tuple of two floats.
SIZE = tuple[float, float]
#: The value type of a setting that is a list of numbers (``turns = [0, 30]``), each checked against
#: the setting's bounds; held as a tuple of floats, at most :data:`ANGLES_MAX` of them.
ANGLES = tuple[float, ...]
#: Most numbers an :data:`ANGLES` setting holds.
ANGLES_MAX = 24
#: The largest finite float (an int beyond it cannot be a float setting).
_FLOAT_MAX = 1.7976931348623157e308
#: Keys shown as they are in messages; any other key is quoted (``repr``).
_PLAIN_KEY = re.compile(r"[A-Za-z0-9_\-.]{1,40}")


@dataclass(frozen=True)
class Spec:
    """How one setting is checked and documented (the metadata of its dataclass field).

    Attributes
    ----------
    doc : str
        One-line meaning.
    unit : str or None
        Unit of a number (``"scene units"``, ``"s"``), None where it has none.
    minimum, maximum : int or float or None
        Inclusive bounds of a number (exclusive where ``exclusive_min``, ``exclusive_max``).
    exclusive_min : bool
        Whether the value must be strictly greater than ``minimum``.
    exclusive_max : bool
        Whether the value must be strictly less than ``maximum``.
    choices : tuple of str or None
        The accepted values of a string.
    default_doc : str or None
        The default in words, where it is not a fixed value (e.g. "the file's stem").
    key : str or None
        The TOML key, where it differs from the field name.
    """

    doc: str
    unit: str | None = None
    minimum: float | None = None
    maximum: float | None = None
    exclusive_min: bool = False
    exclusive_max: bool = False
    choices: tuple[str, ...] | None = None
    default_doc: str | None = None
    key: str | None = None


def setting(default=MISSING, doc: str = "", **spec):
    """A dataclass field for a setting (a scene key, an option): its default and its :class:`Spec`.

    Parameters
    ----------
    default : bool, int, float, str or None
        The value used when the key is absent; leave it out for a required key.
    doc : str
        One-line meaning.
    **spec
        The other fields of :class:`Spec` (``unit``, ``minimum``, ``maximum``, ``exclusive_min``,
        ``exclusive_max``, ``choices``, ``default_doc``, ``key``).

    Returns
    -------
    dataclasses.Field
    """
    return field(default=default, metadata={"spec": Spec(doc, **spec)})


def spec_of(f: dataclasses.Field) -> Spec | None:
    """The :class:`Spec` of a dataclass field, or None for a field that is not a setting."""
    return f.metadata.get("spec")


def field_of(cls: type, name: str) -> dataclasses.Field:
    """The field ``name`` of dataclass ``cls``."""
    return next(f for f in fields(cls) if f.name == name)


def like(cls: type, name: str, *, default=MISSING, **changes):
    """A field declared as ``cls``'s field ``name`` (its default and :class:`Spec`), with
    ``changes`` to the Spec: one setting's default and meaning, used by a second class
    (``default``, if given, replaces the default)."""
    f = field_of(cls, name)
    default = f.default if default is MISSING else default
    return field(default=default, metadata={"spec": dataclasses.replace(spec_of(f), **changes)})


def key_of(f: dataclasses.Field) -> str:
    """The TOML key of a dataclass field."""
    spec = spec_of(f)
    return spec.key if spec is not None and spec.key else f.name


@functools.cache
def value_types(cls: type) -> dict[str, type]:
    """The value type of each field of a dataclass, without ``| None``.

    Parameters
    ----------
    cls : type
        A settings dataclass (fields made by :func:`setting`).

    Returns
    -------
    dict of str to type
        ``bool``, ``int``, ``float``, ``str``, ``list[float]`` (a quaternion),
        ``list[ShapeEntry]`` or a dataclass (a table); ``float | None`` gives ``float``.
    """
    out = {}
    for name, hint in typing.get_type_hints(cls).items():
        if isinstance(hint, types.UnionType):
            hint = next(a for a in typing.get_args(hint) if a is not type(None))
        out[name] = hint
    return out


def describe(cls: type, f: dataclasses.Field) -> str:
    """A field's type and bounds in words, e.g. ``"int 16–4096"`` or ``"number > 0"``.

    The form docs/scene-format.md uses in its type column.
    """
    spec, kind = spec_of(f), value_types(cls)[f.name]
    words = {bool: "bool", int: "int", float: "number", str: "string", list[float]: "[w, x, y, z]",
             SIZE: "[w, h]", ANGLES: "[numbers]"}  # fmt: skip
    word = words.get(kind, "tables")
    exclusive = spec.exclusive_min or spec.exclusive_max
    if spec.minimum is not None and spec.maximum is not None and not exclusive:
        return f"{word} {spec.minimum}–{spec.maximum}"
    bounds = []
    if spec.minimum is not None:
        bounds.append(f"{'>' if spec.exclusive_min else '≥'} {spec.minimum}")
    if spec.maximum is not None:
        bounds.append(f"{'<' if spec.exclusive_max else '≤'} {spec.maximum}")
    text = " ".join([word, ", ".join(bounds)]) if bounds else word
    if spec.choices and kind is float:  # a number, or one of a few words
        text += " or " + " or ".join(f'"{c}"' for c in spec.choices)
    return text


def documented(cls: type) -> type:
    """Class decorator: append a numpydoc ``Attributes`` section built from the fields'
    :class:`Spec` (type and bounds, default, meaning, unit) to the docstring."""
    lines = ["", "    Attributes", "    ----------"]
    for f in fields(cls):
        spec = spec_of(f)
        if spec is None:
            continue
        if spec.default_doc is not None:
            default = spec.default_doc
        elif f.default is MISSING:
            default = "required"
        else:
            default = repr(f.default)
        unit = f" ({spec.unit})" if spec.unit else ""
        lines += [
            f"    {f.name} : {describe(cls, f)}, default {default}",
            f"        {spec.doc[:1].upper()}{spec.doc[1:]}{unit}.",
        ]
        if spec.choices and value_types(cls)[f.name] is not float:
            lines.append(f"        One of: {', '.join(spec.choices)}.")
    cls.__doc__ = (cls.__doc__ or "").rstrip() + "\n" + "\n".join(lines) + "\n"
    return cls


class UnknownSettingError(SieveError, AttributeError):
    """A setting's name that its settings class does not have (a typo): a one-line
    :class:`~sieve_mi.errors.SieveError` that is also the AttributeError Python raises for an
    attribute that cannot be set."""


def refuse_unknown(cls: type, name: str, where: str) -> None:
    """Raise :class:`UnknownSettingError` unless ``name`` is a field of dataclass ``cls``.

    Parameters
    ----------
    cls : type
        A settings dataclass.
    name : str
        The name given (an attribute set, a keyword argument).
    where : str
        What it is a setting of, for the message (``"solver"``, ``"check"``).
    """
    known = [f.name for f in fields(cls)]
    if name not in known:
        raise UnknownSettingError(
            f"{where}: {key_text(name)}: unknown setting; known: {', '.join(sorted(known))}"
        )


def known_names(where: str):
    """Class decorator: a dataclass whose constructor refuses a keyword that is not a field
    (:func:`refuse_unknown`: one line listing the known names) instead of Python's TypeError.

    Used alone by settings tables checked by their own ``__post_init__`` (``ShakeSettings``),
    and by :func:`checked`, which adds the checking of every value.
    """

    def decorate(cls: type) -> type:
        init = cls.__init__

        @functools.wraps(init)
        def __init__(self, *args, **kwargs):
            for name in kwargs:
                refuse_unknown(cls, name, where)
            init(self, *args, **kwargs)

        cls.__init__ = __init__
        return cls

    return decorate


def checked(where: str):
    """Class decorator: a settings dataclass whose values are checked like a scene file's keys
    (:func:`read_value`), in code as in a file.

    Making an instance checks every value it is given (``Solver(particles=-5)``); assigning a
    field of a made instance checks the new value (``scene.solver.particles = -5``): either is
    the one-line :class:`~sieve_mi.errors.SieveError` that ``particles = -5`` in a scene file is,
    at once. A name that is not a field (``scene.solver.particle = 5``, ``Solver(particle=5)``)
    is refused (:class:`UnknownSettingError`), never silently kept.
    """

    def decorate(cls: type) -> type:
        declared = {f.name for f in fields(cls) if spec_of(f) is not None}
        optional = {f.name for f in fields(cls) if f.default is None}  # None: back to the default
        init = known_names(where)(cls).__init__  # an unknown keyword: refused before any value

        @functools.wraps(init)
        def __init__(self, *args, **kwargs):
            init(self, *args, **kwargs)
            for f in fields(cls):  # in their order: the first bad one is named
                value = getattr(self, f.name)
                if f.name in declared and not (value is None and f.name in optional):
                    object.__setattr__(self, f.name, read_value(cls, f.name, value, where))

        def __setattr__(self, name, value):
            refuse_unknown(cls, name, where)
            if (
                name in declared
                and name in self.__dict__
                and not (value is None and name in optional)
            ):
                value = read_value(cls, name, value, where)
            object.__setattr__(self, name, value)

        cls.__init__, cls.__setattr__ = __init__, __setattr__
        return cls

    return decorate


def shown(value, limit: int = 60, spelling: str = "python") -> str:
    """A value as a message shows it: on one line, at most ``limit`` characters.

    ``spelling`` is the language the value was given in: ``"python"`` (code, the command line,
    TOML files) shows its ``repr``; ``"json"`` (a JSON file) its JSON text, so that a JSON file's
    ``null``, ``true`` and ``"text"`` are shown as the file has them, not as Python's ``None``,
    ``True`` and ``'text'``. Never fails: an integer too long to print is described by its
    number of digits, a value nested too deeply to print by its type.

    Examples
    --------
    >>> shown("a" * 100, 10)
    "'aaaaaaaa…"
    >>> shown(10**5000)
    'an integer of 5,001 digits'
    >>> shown([None, True, "x"], spelling="json")
    '[null, true, "x"]'
    """
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 256:
        return f"an integer of {_digits(value):,} digits"
    try:
        if spelling == "json":
            text = json.dumps(value, ensure_ascii=False)
        else:
            text = repr(value).replace("\n", " ")
    except (ValueError, TypeError, RecursionError):
        text = f"<{type(value).__name__}>"
    return cut(text, limit)


def cut(text: str, limit: int = 20) -> str:
    """``text`` cut to ``limit`` characters (an ellipsis marks a cut)."""
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _digits(value: int) -> int:
    """Decimal digits of ``abs(value)``, without converting it to text (Python refuses that for
    more than 4,300 digits)."""
    n = int(abs(value).bit_length() * math.log10(2)) + 1
    return n - 1 if n > 1 and abs(value) < 10 ** (n - 1) else n


def key_text(key) -> str:
    """A key as a message names it: as it is when plain (``solver``, ``mesh_A_pso_iters``), else
    quoted and cut short (:func:`shown`), so a key with a newline stays on one line."""
    return key if isinstance(key, str) and _PLAIN_KEY.fullmatch(key) else shown(key, 40)


class Reader:
    """Type-checked access to one table of settings (of a scene file, a mixture, a command line),
    with errors that name the file (or command) and the key."""

    def __init__(self, path: str, table: dict, where: str, spelling: str = "python"):
        self.path, self.table, self.where = path, table, where
        self.spelling = spelling  # how values are shown (:func:`shown`): "python" or "json"

    def shown(self, value) -> str:
        """``value`` as the messages show it, in the spelling of what gave it (:func:`shown`)."""
        return shown(value, spelling=self.spelling)

    def error(self, key: str, what: str) -> SieveError:
        return SieveError(f"{self.path}: {self.where}{key_text(key)}: {what}")

    def check_keys(self, allowed) -> None:
        for key in self.table:
            if key not in allowed:
                raise self.error(key, f"unknown key; known keys here: {', '.join(sorted(allowed))}")

    def read(self, cls: type) -> dict:
        """The keys of ``cls`` present in this table, checked against their :class:`Spec`."""
        kinds = value_types(cls)
        values = {}
        for f in fields(cls):
            spec = spec_of(f)
            if spec is not None and key_of(f) in self.table and kinds[f.name] in _READERS:
                values[f.name] = _READERS[kinds[f.name]](self, key_of(f), spec)
        return values

    def value(self, cls: type, name: str, key: str):
        """The value under ``key`` of this table, checked as field ``name`` of ``cls``."""
        return _READERS[value_types(cls)[name]](self, key, spec_of(field_of(cls, name)))

    def number(self, key: str, spec: Spec, integer: bool = False):
        value = self.table[key]
        if isinstance(value, str) and spec.choices and not integer:
            if value in spec.choices:
                return value
            words = " or ".join(repr(c) for c in spec.choices)
            raise self.error(key, f"expected a number or {words}, got {self.shown(value)}")
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(
                key,
                f"expected a {'whole number' if integer else 'number'}, got {self.shown(value)}",
            )
        if not (isinstance(value, int) or math.isfinite(value)):  # an int of any size is finite
            raise self.error(key, f"expected a finite number, got {self.shown(value)}")
        if integer and isinstance(value, float) and not value.is_integer():
            raise self.error(key, f"expected a whole number, got {self.shown(value)}")
        low, high = spec.minimum, spec.maximum
        if low is not None and (value <= low if spec.exclusive_min else value < low):
            raise self.error(
                key, f"must be {'>' if spec.exclusive_min else '>='} {low}, got {self.shown(value)}"
            )
        if high is not None and (value >= high if spec.exclusive_max else value > high):
            raise self.error(
                key,
                f"must be {'<' if spec.exclusive_max else '<='} {high}, got {self.shown(value)}",
            )
        if integer or abs(value) <= _FLOAT_MAX:
            return int(value) if integer else float(value)
        raise self.error(key, f"{self.shown(value)} is beyond a number's range (±1.8e308)")

    def integer(self, key: str, spec: Spec) -> int:
        return self.number(key, spec, integer=True)

    def boolean(self, key: str, spec: Spec) -> bool:
        value = self.table[key]
        if not isinstance(value, bool):
            raise self.error(key, f"expected true or false, got {self.shown(value)}")
        return value

    def string(self, key: str, spec: Spec) -> str:
        value = self.table[key]
        if not isinstance(value, str) or not value:
            raise self.error(key, f"expected a non-empty string, got {self.shown(value)}")
        if spec.choices is not None and value not in spec.choices:
            raise self.error(key, f"{self.shown(value)} is not one of: {', '.join(spec.choices)}")
        return value

    def quaternion(self, key: str, spec: Spec) -> list[float]:
        """A rotation (w, x, y, z) of norm 1 (to 1e-3), returned normalised."""
        q = self.table[key]
        if not (
            isinstance(q, list)
            and len(q) == 4
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in q)
        ):
            raise self.error(key, f"expected a quaternion [w, x, y, z], got {self.shown(q)}")
        if any(abs(v) > _FLOAT_MAX for v in q if isinstance(v, int)):
            raise self.error(key, f"quaternion {self.shown(q)} has a number beyond ±1.8e308")
        qn = np.asarray(q, float)
        with np.errstate(over="ignore", invalid="ignore"):  # 1e308 squared: inf, refused below
            norm = float(np.linalg.norm(qn))
        if not np.all(np.isfinite(qn)) or norm < 1e-9:
            raise self.error(key, f"quaternion {self.shown(q)} has no direction")
        if abs(norm - 1.0) > 1e-3:
            raise self.error(
                key,
                f"quaternion {self.shown(q)} is not a unit quaternion (norm {norm:.4g}); divide it "
                "by its norm",
            )
        return [float(v) for v in qn / norm]

    def numbers(self, key: str, spec: Spec, count: int | None = None) -> tuple:
        """A list of numbers (``count`` of them, or 1 to :data:`ANGLES_MAX`), each within the
        setting's bounds; returned as a tuple of floats."""
        values = self.table[key]
        wanted = f"a list of {count} numbers" if count else "a list of numbers"
        if not isinstance(values, list | tuple) or not values:
            raise self.error(key, f"expected {wanted}, got {self.shown(values)}")
        if (count and len(values) != count) or len(values) > ANGLES_MAX:
            most = f" (at most {ANGLES_MAX})" if not count else ""
            raise self.error(key, f"expected {wanted}{most}, got {self.shown(values)}")
        out = []
        for v in values:
            item = Reader(self.path, {key: v}, self.where, self.spelling)
            out.append(item.number(key, dataclasses.replace(spec, choices=None)))
        return tuple(out)

    def size(self, key: str, spec: Spec) -> tuple:
        """A width and a height (:data:`SIZE`)."""
        return self.numbers(key, spec, 2)


_READERS = {
    bool: Reader.boolean,
    int: Reader.integer,
    float: Reader.number,
    str: Reader.string,
    list[float]: Reader.quaternion,
    SIZE: Reader.size,
    ANGLES: Reader.numbers,
}


def read_value(
    cls: type, name: str, value, where: str, key: str | None = None, spelling: str = "python"
):
    """A value of field ``name`` of ``cls`` given outside a scene file, checked as a key of one.

    Parameters
    ----------
    cls : type
        A settings dataclass (:class:`~sieve_mi.scene.Verdict`,
        :class:`~sieve_mi.game.check_settings.CheckSettings`, ...).
    name : str
        The field.
    value : bool, int, float, str or list
        The value as given; text that should have been a number is reported as such.
    where : str
        What gave it, for the message (e.g. ``"check"``, the command).
    key : str, optional
        The name it was given under (e.g. ``"--learning-rate"``); default its TOML key.
    spelling : {"python", "json"}
        How the message shows the value (:func:`shown`): ``"json"`` for a JSON file's value.

    Returns
    -------
    bool, int, float, str or list
        The value (a whole float for an int field as int, an int for a float field as float).

    Raises
    ------
    SieveError
        ``"{where}: {key}: {what}"``, the line a bad key of a scene file gets.

    Examples
    --------
    >>> @dataclass
    ... class Search:
    ...     learning_rate: float = setting(0.05, "Adam's learning rate", minimum=0,
    ...                                    exclusive_min=True, maximum=1)
    >>> read_value(Search, "learning_rate", 0.0, "check", "--learning-rate")
    Traceback (most recent call last):
    ...
    sieve_mi.errors.SieveError: check: --learning-rate: must be > 0, got 0.0
    >>> read_value(Search, "learning_rate", 1, "check")
    1.0
    """
    key = key or key_of(field_of(cls, name))
    return Reader(where, {key: value}, "", spelling).value(cls, name, key)


#: Longest name a scene or shape may have (names go into file and folder names, 255 bytes at most).
NAME_MAX = 100


def check_name(path: str, where: str, name: str) -> None:
    """Raise unless ``name`` is a usable label: at most :data:`NAME_MAX` characters, no control
    characters (newlines, tabs, NUL), not blank and not padded with spaces."""
    if len(name) > NAME_MAX:
        raise SieveError(f"{path}: {where}: {len(name)} characters; use at most {NAME_MAX}")
    if any(ord(c) < 32 or ord(c) == 127 for c in name) or name != name.strip() or not name:
        raise SieveError(
            f"{path}: {where}: {name[:40]!r} has control characters or blank space at its ends; "
            "use letters, digits, '-' and '_'"
        )


def check_folder_name(path: str, name: str, key: str = "name") -> None:
    """Raise unless ``name`` (given as ``key``) can be one folder's name: a usable label
    (:func:`check_name`) with no separators, NUL, '.' or '..'."""
    check_name(path, key, name)
    if any(c in name for c in "/\\\0") or name in (".", ".."):
        raise SieveError(
            f"{path}: {key}: {name!r} is used as a folder name; use letters, digits, '-' and '_'"
        )
