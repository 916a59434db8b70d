"""TOML and JSON text read with every number and nesting checked: one line naming file and key.

Python's readers (``tomllib``, ``json``) accept what no reader of sieve-mi should meet, or fail
on it with an exception that names no key: an integer of more than :data:`DIGITS_MAX` digits
(ValueError), a float beyond ±1.8e308 (silently ``inf``), arrays nested past the recursion limit
(RecursionError), a JSON key given twice (the later one silently wins). :func:`parse_toml` and
:func:`parse_json` refuse each with one :class:`~sieve_mi.errors.SieveError` line naming the
file, the key and, where the parser gave up, the line (``scene.toml: solver.steps (line 6): an
integer of more than 4,300 digits; give a smaller number``). Scene files and mixtures
(:mod:`sieve_mi.scene`) and the paper authors' configurations are read here.
"""

from __future__ import annotations

import json
import math
import re
import tomllib

from sieve_mi.errors import SieveError
from sieve_mi.settings import cut, key_text, shown

__all__ = ["DIGITS_MAX", "NESTING_MAX", "parse_json", "parse_toml"]

#: Deepest nesting of arrays and tables a scene file or a configuration may have (a scene needs
#: three: a ``[[pass]]`` list, its table, a rotation); deeper is refused before Python's recursion
#: limit is reached.
NESTING_MAX = 32
#: Most digits of an integer a file may give (Python's own limit of text-to-int conversion; no
#: setting takes more than 20 digits, so only the message is at stake).
DIGITS_MAX = 4300
#: Bits of the largest integer of :data:`DIGITS_MAX` digits.
_BITS_MAX = int(DIGITS_MAX * math.log2(10))


def _trail_text(trail: tuple) -> str:
    """A value's place in a parsed document, e.g. ``pass[0].rotation`` (at most 6 steps)."""
    text = ""
    for i, step in enumerate(trail):
        if i == 6:
            return text + ".…"
        text += f"[{step}]" if isinstance(step, int) else ("." if text else "") + key_text(step)
    return text or "(top level)"


class _Unreadable:
    """A number a file gives that Python cannot hold (an integer of more than
    :data:`DIGITS_MAX` digits, a float beyond ±1.8e308): a marker in the parsed document, so that
    :func:`_check_document` refuses it naming its key."""

    def __init__(self, what: str):
        self.what = what


def _parse_float(text: str):
    """A float literal of a TOML or JSON file: the float, or :class:`_Unreadable` where it is
    out of a float's range (Python would make it ``inf`` without a word)."""
    value = float(text)
    if math.isinf(value) and text.lstrip("+-")[:3].lower() != "inf":
        return _Unreadable(f"{cut(text)} is beyond a number's range (±1.8e308)")
    return value


def _parse_int(text: str):
    """An integer literal of a JSON file: the int, or :class:`_Unreadable` beyond
    :data:`DIGITS_MAX` digits."""
    if len(text.lstrip("-")) > DIGITS_MAX:
        return _Unreadable(f"an integer of {len(text.lstrip('-')):,} digits")
    return int(text)


def _check_document(data, path: str, max_depth: int | None) -> None:
    """Refuse, naming the key, what a parsed document holds that no reader should meet: a number
    Python cannot hold (:class:`_Unreadable`, an integer of over :data:`DIGITS_MAX` digits) or,
    with ``max_depth``, arrays and tables nested deeper than that (walked without recursion)."""
    stack = [(data, (), 0)]
    while stack:
        value, trail, depth = stack.pop()
        if isinstance(value, _Unreadable):
            raise SieveError(f"{path}: {_trail_text(trail)}: {value.what}; give a smaller number")
        if (
            isinstance(value, int)
            and not isinstance(value, bool)
            and value.bit_length() > _BITS_MAX
        ):
            raise SieveError(f"{path}: {_trail_text(trail)}: {shown(value)}; give a smaller number")
        if isinstance(value, dict):
            children = value.items()
        elif isinstance(value, list):
            children = enumerate(value)
        else:
            continue
        if max_depth is not None and depth > max_depth:
            raise SieveError(
                f"{path}: {_trail_text(trail)}: arrays or tables nested more than {max_depth} "
                "deep; give numbers, strings and short lists"
            )
        stack.extend((v, (*trail, k), depth + 1) for k, v in children)


#: What a key, a table header, a string or a bracket of a TOML or JSON text looks like (for
#: :func:`_where_in_text`, which names the place of an error that the parser did not).
_TOKENS = re.compile(
    r'"""[\s\S]*?"""|\'\'\'[\s\S]*?\'\'\'|"(?:\\.|[^"\\\n])*"|\'[^\'\n]*\'|#[^\n]*|[\[\]{}]'
)
_TOML_KEY = re.compile(r"(?m)^[ \t]*([^\s=#\[][^=\n]*?)[ \t]*=")
_TOML_TABLE = re.compile(r"(?m)^[ \t]*\[\[?[ \t]*([^\]\n]+?)[ \t]*\]")
_JSON_KEY = re.compile(r'"((?:\\.|[^"\\\n]){0,40})"\s*:')


def _where_in_text(text: str, pos: int, toml: bool) -> str:
    """The key and line at character ``pos`` of a TOML or JSON text, e.g. ``solver.particles
    (line 7)``: the last key given before it, under its table (a heuristic, for messages)."""
    head, line = text[:pos], text.count("\n", 0, pos) + 1
    if toml:
        keys, tables = list(_TOML_KEY.finditer(head)), list(_TOML_TABLE.finditer(head))
        key = keys[-1].group(1).strip() if keys else ""
        if tables and (not keys or tables[-1].start() < keys[-1].start()):
            key = f"{tables[-1].group(1).strip()}.{key}" if key else tables[-1].group(1).strip()
    else:
        keys = list(_JSON_KEY.finditer(head))
        key = keys[-1].group(1) if keys else ""
    return f"{key_text(key) if key else '(top level)'} (line {line})"


def _too_deep_at(text: str) -> int:
    """Where a TOML or JSON text first opens an array or table deeper than :data:`NESTING_MAX`
    (strings and comments skipped); 0 if nowhere."""
    depth = 0
    for m in _TOKENS.finditer(text):
        token = m.group()
        if token in "[{":
            depth += 1
            if depth > NESTING_MAX:
                return m.start()
        elif token in "]}":
            depth = max(depth - 1, 0)
    return 0


def _too_long_at(text: str) -> int:
    """Where a TOML text gives an integer of more than :data:`DIGITS_MAX` digits; 0 if nowhere."""
    for m in re.finditer(r"[0-9][0-9_]*", text):  # each run once: linear in the text
        if m.end() - m.start() > DIGITS_MAX and len(m.group().replace("_", "")) > DIGITS_MAX:
            return m.start()
    return 0


def parse_toml(text: str, path: str) -> dict:
    """A TOML document, every number and nesting checked: one line naming the file and key.

    Parameters
    ----------
    text : str
        The file's text (a leading byte-order mark is dropped).
    path : str
        The file, for messages.

    Returns
    -------
    dict

    Raises
    ------
    SieveError
        Invalid TOML; an integer of more than :data:`DIGITS_MAX` digits or a float beyond
        ±1.8e308; arrays or tables nested deeper than :data:`NESTING_MAX`.

    Examples
    --------
    >>> parse_toml("[solver]\\nparticles = " + "9" * 5000, "s.toml")
    Traceback (most recent call last):
    ...
    sieve_mi.errors.SieveError: s.toml: solver.particles (line 2): an integer of more than 4,300 digits; give a smaller number
    """
    text = text.removeprefix("\ufeff")  # a byte-order mark is not TOML's
    try:
        data = tomllib.loads(text, parse_float=_parse_float)
    except tomllib.TOMLDecodeError as exc:
        raise SieveError(f"{path}: not valid TOML ({exc})") from None
    except RecursionError:
        where = _where_in_text(text, _too_deep_at(text), toml=True)
        raise SieveError(f"{path}: {where}: arrays or tables nested more than {NESTING_MAX} "
                         "deep; give numbers, strings and short lists") from None  # fmt: skip
    except ValueError:  # int() of tomllib: more digits than Python converts
        where = _where_in_text(text, _too_long_at(text), toml=True)
        raise SieveError(f"{path}: {where}: an integer of more than {DIGITS_MAX:,} digits; "
                         "give a smaller number") from None  # fmt: skip
    _check_document(data, path, NESTING_MAX)
    return data


def parse_json(text: str, path: str, max_depth: int | None = NESTING_MAX):
    """A JSON document, every number, key and nesting checked: one line naming the file and key.

    The reader every JSON input of sieve-mi should use instead of ``json.load``: Python's reader
    lets a later duplicate key replace the earlier one silently, turns a float beyond ±1.8e308
    into ``inf``, and raises ValueError or RecursionError on a long integer or deep nesting.

    Parameters
    ----------
    text : str
        The file's text.
    path : str
        The file, for messages.
    max_depth : int or None
        Deepest nesting of arrays and objects accepted (None: any that Python parses, as a
        certificate's tree needs).

    Returns
    -------
    object
        The document (dict, list, str, int, float, bool or None).

    Raises
    ------
    SieveError
        Invalid JSON; a key given twice in one object; an integer of more than
        :data:`DIGITS_MAX` digits or a float beyond ±1.8e308; nesting deeper than ``max_depth``
        (or than Python can parse).

    Examples
    --------
    >>> parse_json('{"a": 1, "a": 2}', "c.json")
    Traceback (most recent call last):
    ...
    sieve_mi.errors.SieveError: c.json: a: given twice in one object; keep one
    """

    def unique(pairs):
        out = {}
        for key, value in pairs:
            if key in out:
                raise SieveError(f"{path}: {key_text(key)}: given twice in one object; keep one")
            out[key] = value
        return out

    try:
        data = json.loads(text, object_pairs_hook=unique, parse_int=_parse_int,
                          parse_float=_parse_float)  # fmt: skip
    except json.JSONDecodeError as exc:
        raise SieveError(f"{path}: not valid JSON ({exc})") from None
    except RecursionError:
        where = _where_in_text(text, _too_deep_at(text), toml=False)
        raise SieveError(f"{path}: {where}: arrays or objects nested too deeply; give numbers, "
                         "strings and short lists") from None  # fmt: skip
    _check_document(data, path, max_depth)
    return data
