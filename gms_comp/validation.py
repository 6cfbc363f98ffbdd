"""One validation layer for everything that comes from outside.

Configs, tables, traces, sweep files and command-line values are untrusted. Every
refusal is an :class:`InputError` (or a subclass: ``ConfigError``, ``TableError``,
``TraceError``): one line ``SOURCE: FIELD: PROBLEM`` (the file or the option, the
key/row/column, what is wrong), turned by the CLI into exit code 2.

Resources are bounded before they are spent: a file is measured before it is read,
decoded as strict UTF-8, its bracket nesting counted before a parser recurses into it,
and element, sample, point and load counts are compared with the caps below before any
array is made. docs/limits.md lists every bound (a test keeps it in step with the code).

Numbers are checked before they are converted (:func:`finite_float`: a 400-digit integer
is refused, not overflowed), JSON documents field by field (:class:`JsonReader`). Values
and paths on the command line are checked in :mod:`gms_comp.arguments`.
"""

from __future__ import annotations

import json
import math
import os
import re
import sys
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

from gms_comp.errors import ConfigError, InputError

#: A config or sweep file larger than this is refused before it is parsed.
MAX_CONFIG_BYTES = 4 << 20
#: A table file larger than this is refused before it is parsed (a 1024-element table
#: with a 64-load family is about 2 MB).
MAX_TABLE_BYTES = 32 << 20
#: A CSV trace larger than this is refused before it is read.
MAX_TRACE_BYTES = 256 << 20
#: Samples of a trace (CSV rows, or a MATLAB variable's declared size before loading):
#: about 200 s at 10 kHz; every column costs 8 bytes per sample, the CSV reader ~30.
MAX_TRACE_SAMPLES = 2_000_000
#: Bracket nesting in a TOML or JSON document (ours need 3; parsers recurse per level).
MAX_NESTING_DEPTH = 16
#: Elements of a GMS table (the reduction fits at most [table] elements' upper bound).
MAX_TABLE_ELEMENTS = 1024
#: Ball loads of one ball set (a carriage has tens of balls; each distinct load costs a
#: steady-state search).
MAX_BALL_LOADS = 1024
#: Loads of a table's load family (each one a full refit).
MAX_FAMILY_LOADS = 64
#: Points of a sweep grid (each a table fit of seconds to minutes).
MAX_SWEEP_POINTS = 10_000
#: Worker processes of a local Dask cluster.
MAX_WORKERS = 256
#: Random seeds (config keys and ``--seed``): 0 to 2**32 - 1, what every numpy generator
#: takes (a negative seed is refused, not passed on to fail inside the run).
MAX_SEED = 2**32 - 1

ErrorType = Callable[[str, str, str], InputError]

#: Characters of a bad value quoted in a refusal (a longer one is cut, its length said).
MAX_SHOWN_CHARS = 60


def shown(value: Any) -> str:
    """``repr(value)`` for a one-line refusal, cut to :data:`MAX_SHOWN_CHARS` (a
    400-digit integer or a 1 MB string is named, not printed)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 200:
        return f"an integer of {len(str(abs(value)))} digits"
    text = repr(value)
    if len(text) > MAX_SHOWN_CHARS:
        return f"{text[: MAX_SHOWN_CHARS - 3]}... ({len(text)} characters)"
    return text


def is_number(value: Any) -> bool:
    """Whether ``value`` is an int or a float (a boolean is not a number)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def finite_float(value: Any) -> float | None:
    """``value`` as a finite float, or None: not a number, NaN, infinite, or an integer
    beyond the float range (checked before converting: ``float(10**400)`` overflows)."""
    if not is_number(value):
        return None
    if isinstance(value, int):
        return float(value) if abs(value) <= _FLOAT_MAX_INT else None
    return float(value) if math.isfinite(value) else None


_FLOAT_MAX_INT = int(sys.float_info.max)


def read_text(
    path: str | os.PathLike[str],
    *,
    max_bytes: int,
    what: str = "file",
    error: ErrorType = InputError,
) -> str:
    """The UTF-8 text of ``path``, refusing a missing, oversized or non-UTF-8 file.

    The size is taken from the file system before anything is read.
    """
    p = Path(path)
    try:
        size = p.stat().st_size
        if not p.is_file():
            raise error(str(p), "", f"is not a {what} (a folder or a device)")
        if size > max_bytes:
            raise error(str(p), "", f"{size} bytes, more than the {max_bytes} a {what} may have")
        data = p.read_bytes()
    except FileNotFoundError:
        raise error(str(p), "", "file not found") from None
    except OSError as err:
        raise error(str(p), "", f"cannot read file ({err.strerror})") from None
    return decode_utf8(data, str(p), error=error)


def decode_utf8(data: bytes, source: str, *, error: ErrorType = InputError) -> str:
    """``data`` decoded as strict UTF-8 (a leading byte-order mark, as some editors write
    one, is dropped); a bad byte is reported with its line."""
    try:
        text = data.decode("utf-8").removeprefix("\ufeff")
    except UnicodeDecodeError as err:
        line = data[: err.start].count(b"\n") + 1
        raise error(
            source, f"line {line}", f"byte 0x{data[err.start]:02x} is not UTF-8 text"
        ) from None
    if "\x00" in text:
        line = text[: text.index("\x00")].count("\n") + 1
        raise error(source, f"line {line}", "holds a NUL character: not a text file")
    return text


_STRUCTURE = re.compile(r"""[\[\]{}"'#\n\\]""")


def nesting_depth(text: str) -> int:
    """Deepest nesting of ``[``/``{`` outside strings and comments (TOML and JSON).

    Only the structural characters are visited (a regular expression finds them), so a
    10 MB document of numbers is measured in milliseconds.
    """
    depth = deepest = 0
    quote = ""
    escaped = comment = False
    last = -2
    for match in _STRUCTURE.finditer(text):
        ch, at = match.group(), match.start()
        if escaped and at != last + 1:
            escaped = False  # the backslash escaped an ordinary character
        last = at
        if comment:
            comment = ch != "\n"
        elif quote:
            if escaped:
                escaped = False
            elif ch == "\\" and quote == '"':
                escaped = True
            elif ch == quote:
                quote = ""
        elif ch in "\"'":
            quote = ch
        elif ch == "#":
            comment = True
        elif ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
    return deepest


def _check_depth(text: str, source: str, error: ErrorType) -> None:
    depth = nesting_depth(text)
    if depth > MAX_NESTING_DEPTH:
        raise error(source, "", f"brackets nested {depth} deep, more than {MAX_NESTING_DEPTH}")


def read_toml_document(
    path: str | os.PathLike[str], *, error: ErrorType = ConfigError
) -> dict[str, Any]:
    """Parse a TOML file within the size, encoding and nesting bounds."""
    text = read_text(path, max_bytes=MAX_CONFIG_BYTES, what="config file", error=error)
    _check_depth(text, str(path), error)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise error(str(path), "", f"not valid TOML ({err})") from None
    except RecursionError:
        raise error(str(path), "", "nested too deeply to parse") from None


def parse_json(text: str, source: str, *, error: ErrorType = InputError) -> Any:
    """Parse JSON text, refusing NaN/Infinity and documents nested too deeply."""
    _check_depth(text, source, error)
    try:
        return json.loads(text, parse_constant=_refuse_constant)
    except json.JSONDecodeError as err:
        raise error(source, "", f"truncated or not JSON ({err})") from None
    except RecursionError:
        raise error(source, "", "nested too deeply to parse") from None
    except ValueError as err:
        raise error(source, "", str(err)) from None


def _refuse_constant(name: str) -> float:
    raise ValueError(f"non-finite number {name} is not allowed")


def check_count(
    source: str, field: str, count: int, cap: int, what: str, *, error: ErrorType = InputError
) -> None:
    """Refuse ``count`` items of ``what`` when it exceeds ``cap`` (before allocating them)."""
    if count > cap:
        raise error(source, field, f"{count} {what}, more than the {cap} allowed")


class JsonReader:
    """Field accessors for a parsed JSON document, each refusal one line naming the source
    and the field's dotted path (``velocity_level.slip_level``, ``limit_N[3]``).

    Numbers are checked without converting first (a 400-digit integer is refused, not
    overflowed), lists are measured before their entries are read.
    """

    def __init__(self, source: str, error: ErrorType = InputError) -> None:
        self.source = source
        self._error = error

    def error(self, key: str, reason: str) -> InputError:
        """The refusal of field ``key``."""
        return self._error(self.source, key, reason)

    def get(self, obj: Any, key: str) -> Any:
        """``obj[last part of key]``; a missing key is reported with its full name."""
        name = key.rsplit(".", 1)[-1]
        if not isinstance(obj, dict):
            parent = key.rsplit(".", 1)[0]
            raise self.error(parent, "must be a JSON object")
        if name not in obj:
            raise self.error(key, "missing")
        return obj[name]

    def number(self, obj: Any, key: str, positive: bool, hi: float) -> float:
        """``obj``'s field ``key``: see :meth:`check_number`."""
        return self.check_number(self.get(obj, key), key, positive, hi)

    def check_number(self, value: Any, key: str, positive: bool, hi: float) -> float:
        """A finite number, > 0 when ``positive`` else >= 0, and <= ``hi``."""
        if not is_number(value):
            raise self.error(key, f"must be a number, got {shown(value)}")
        number = finite_float(value)
        if number is None or (number <= 0 if positive else number < 0) or number > hi:
            lower = "(0" if positive else "[0"
            raise self.error(key, f"must be in {lower}, {hi:g}], got {shown(value)}")
        return number

    def vector(self, value: Any, key: str, n: int | None, positive: bool, hi: float) -> list[float]:
        """A list of ``n`` numbers (any non-zero length when ``n`` is None)."""
        if not isinstance(value, list) or not value or (n is not None and len(value) != n):
            raise self.error(key, f"must be a list of {n or 'some'} numbers")
        return [self.check_number(v, f"{key}[{i}]", positive, hi) for i, v in enumerate(value)]

    def string(self, obj: Any, key: str) -> str:
        """``obj``'s field ``key``, a string."""
        value = self.get(obj, key)
        if not isinstance(value, str):
            raise self.error(key, f"must be a string, got {shown(value)}")
        return value
