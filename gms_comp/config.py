"""Validated loading of TOML configs into frozen dataclasses.

Every section of a config file maps to a frozen dataclass whose field names
carry their units (``ball_radius_m``, ``normal_load_N``). Values are SI.
A field without a default is required. A field may carry a check in its
metadata (``field(metadata=positive(1e3))``); a dataclass may add cross-field
checks through a ``problems()`` method returning ``(key, reason)`` pairs.

Sections are owned by the layer that uses them; :data:`KNOWN_SECTIONS` lists
every section name a gms-comp config may hold, so that a misspelt section is
refused wherever the file is read.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import types
import typing
from collections.abc import Callable, Mapping
from importlib import resources
from pathlib import Path
from typing import Any, Literal, TypeVar

from gms_comp.errors import ConfigError
from gms_comp.validation import finite_float, is_number, read_toml_document, shown

KNOWN_SECTIONS = frozenset(
    {
        "bearing",  # ball, raceway, material, friction (physics)
        "stand",  # loads and kinematics of the ball set (physics)
        "model",  # numerical and modelling choices of the ball model (physics)
        "table",  # GMS reduction settings (reduction)
        "plant",  # simulated linear-motor axis (sim)
        "controller",  # cascade controller (sim)
        "scenario",  # trajectory and delays (sim)
        "compensator",  # observer and feedforward (runtime)
        "can",  # CAN transport (firmware_bridge)
        "machine",  # the simulated machine behind gms-comp machine (sim)
        "diagnosis",  # measured-data analysis
        "scaleout",  # Dask scheduler address and TLS files (application)
    }
)

Check = Callable[[Any], "str | None"]

T = TypeVar("T")


def positive(hi: float, *, max_items: int | None = None) -> dict[str, Any]:
    """Field metadata: 0 < value <= ``hi`` (at most ``max_items`` entries).

    Every number a config holds has a finite range, so that no duration, rate or count
    read from a file can overflow or allocate without bound; :func:`field_range` reads it.
    """
    return in_range(0.0, hi, lo_open=True, max_items=max_items)


def non_negative(hi: float) -> dict[str, Any]:
    """Field metadata: 0 <= value <= ``hi``."""
    return in_range(0.0, hi)


def in_range(
    lo: float,
    hi: float,
    *,
    hi_open: bool = False,
    lo_open: bool = False,
    max_items: int | None = None,
) -> dict[str, Any]:
    """Field metadata: lo <= value <= hi (``lo_open``/``hi_open`` make a bound strict).

    ``max_items`` caps the number of entries of an array field; it is checked before
    the entries are. The bounds are the field's declared range (:class:`FieldRange`),
    which ``gms-comp config``, docs/limits.md and the property tests read.
    """
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
        raise ValueError(f"a field's range must be finite, got [{lo}, {hi}]")  # a code error
    declared = FieldRange(lo, hi, lo_open, hi_open, max_items)

    def check(v: Any) -> str | None:
        return None if _all(v, declared.contains) else f"must be in {declared}"

    lower = "(" if lo_open else "["
    upper = ")" if hi_open else "]"
    return {
        "check": check,
        "range": (lo, hi, lower, upper),
        "bounds": declared,
        "max_items": max_items,
    }


@dataclasses.dataclass(frozen=True)
class FieldRange:
    """The declared range of a numeric config field (and of its entries, for an array)."""

    lo: float
    hi: float
    lo_open: bool = False
    hi_open: bool = False
    max_items: int | None = None

    def contains(self, x: float) -> bool:
        """Whether the number ``x`` (an int of any size, or a finite float) is inside."""
        above = self.lo < x if self.lo_open else self.lo <= x
        below = x < self.hi if self.hi_open else x <= self.hi
        return above and below

    def __str__(self) -> str:
        lower = "(" if self.lo_open else "["
        upper = ")" if self.hi_open else "]"
        return f"{lower}{_bound(self.lo)}, {_bound(self.hi)}{upper}"


def _bound(x: float) -> str:
    """A bound as written: an integer in full (a seed's 4294967295), a float with :g."""
    return str(x) if isinstance(x, int) else f"{x:g}"


def field_range(f: dataclasses.Field[Any]) -> FieldRange | None:
    """The declared range of a config dataclass field, None for one without (text,
    booleans, choices)."""
    bounds = f.metadata.get("bounds")
    return bounds if isinstance(bounds, FieldRange) else None


def _all(value: Any, pred: Callable[[float], bool]) -> bool:
    items = value if isinstance(value, tuple) else (value,)
    return all(_finite(x) and pred(x) for x in items)


def _finite(x: Any) -> bool:
    """An int of any size is finite (``math.isfinite`` overflows on a 400-digit one)."""
    return isinstance(x, int) or math.isfinite(x)


def default_config_path() -> Path:
    """The packaged default config: the seed's Table 1 and its test stand."""
    return Path(str(resources.files("gms_comp.configs").joinpath("table1.toml")))


def read_toml(path: str | Path) -> dict[str, Any]:
    """Read a config file and refuse unreadable TOML or unknown sections."""
    p = Path(path)
    doc = read_toml_document(p, error=ConfigError)
    for name, value in doc.items():
        if name not in KNOWN_SECTIONS:
            raise ConfigError(
                str(p), name, f"unknown section (known: {', '.join(sorted(KNOWN_SECTIONS))})"
            )
        if not isinstance(value, dict):
            raise ConfigError(str(p), name, "must be a [section] table")
    return doc


def config_hash(path: str | Path) -> str:
    """SHA-256 of a config file's bytes, to tie derived artefacts to their source."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def why(text: str) -> dict[str, Any]:
    """Field metadata: one line on why the key exists and why its default is what it is
    (listed in docs/config.md); combine with a check, ``in_range(0, 1) | why("...")``."""
    return {"why": text}


def key(default: Any, check: dict[str, Any], reason: str) -> Any:
    """A config field with its ``default``, its ``check`` (:func:`in_range`, ...) and the
    one line of why (:func:`why`)."""
    return dataclasses.field(default=default, metadata=check | why(reason))


def parse_section(doc: Mapping[str, Any], path: str | Path, section: str, cls: type[T]) -> T:
    """Build dataclass ``cls`` from ``doc[section]``, validating keys, types and values.

    A missing section is allowed when every field of ``cls`` has a default. A field whose
    type is itself a config dataclass is a sub-section, ``[section.field]`` in TOML.
    """
    return _parse_table(doc.get(section, {}), str(path), section, cls)


def _parse_table(table: Any, where: str, section: str, cls: type[T]) -> T:
    """:func:`parse_section` of one table (``section``: its dotted name, for messages)."""
    if not isinstance(table, Mapping):
        raise ConfigError(where, section, "must be a [section] table")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    for key in table:
        if key not in fields:
            raise ConfigError(
                where, f"{section}.{key}", f"unknown key (known: {', '.join(fields)})"
            )
    values: dict[str, Any] = {}
    for name, f in fields.items():
        key = f"{section}.{name}"
        if name not in table:
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                raise ConfigError(where, key, "missing required key")
            continue
        if is_section(hints[name]):
            values[name] = _parse_table(table[name], where, key, hints[name])
            continue
        cap = f.metadata.get("max_items")
        if cap is not None and isinstance(table[name], list) and len(table[name]) > cap:
            raise ConfigError(
                where, key, f"{len(table[name])} entries, more than the {cap} allowed"
            )
        raw = table[name]
        check = f.metadata.get("check")
        # The range first, on the value as written (an int of any size compares exactly;
        # converting a 400-digit one to float would overflow), then the type.
        if check is not None and _numeric(raw):
            reason = check(tuple(raw) if isinstance(raw, list) else raw)
            if reason:
                raise ConfigError(where, key, f"{reason}, got {shown(raw)}")
        value = _coerce(raw, hints[name], where, key)
        if check is not None:
            reason = check(value)
            if reason:
                raise ConfigError(where, key, f"{reason}, got {shown(raw)}")
        values[name] = value
    obj = cls(**values)
    problems = getattr(obj, "problems", None)
    if problems is not None:
        for name, reason in problems():
            raise ConfigError(where, f"{section}.{name}", reason)
    return obj


def _numeric(raw: Any) -> bool:
    """Whether ``raw`` is a number or a non-empty array of numbers (booleans are not)."""
    items = raw if isinstance(raw, list) and raw else [raw]
    return all(is_number(x) for x in items)


def is_section(hint: Any) -> bool:
    """Whether a field of this type is a sub-section (a config dataclass)."""
    return isinstance(hint, type) and dataclasses.is_dataclass(hint)


def _coerce(value: Any, hint: Any, where: str, key: str) -> Any:
    """Check ``value`` against a type hint; ints are accepted where floats are expected."""
    origin = typing.get_origin(hint)
    if origin is Literal:
        choices = typing.get_args(hint)
        # exactly one of them: True is not 1, nor 1.0 the choice 1
        if not any(type(value) is type(c) and value == c for c in choices):
            raise ConfigError(
                where, key, f"must be one of {', '.join(map(repr, choices))}, got {shown(value)}"
            )
        return value
    if origin in (typing.Union, types.UnionType):
        args = typing.get_args(hint)
        last: ConfigError | None = None
        for arg in args:
            try:
                return _coerce(value, arg, where, key)
            except ConfigError as err:
                last = err
        assert last is not None
        raise last
    if origin is tuple:
        (item, _ellipsis) = typing.get_args(hint)
        if not isinstance(value, list) or not value:
            raise ConfigError(where, key, f"must be a non-empty array, got {shown(value)}")
        return tuple(_coerce(v, item, f"{where}", f"{key}[{i}]") for i, v in enumerate(value))
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(
                where, key, f"must be a number, got {type(value).__name__} {shown(value)}"
            )
        number = finite_float(value)
        if number is None:
            raise ConfigError(where, key, f"must be a finite number, got {shown(value)}")
        return number
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(
                where, key, f"must be an integer, got {type(value).__name__} {shown(value)}"
            )
        return value
    if hint is bool:
        if not isinstance(value, bool):
            raise ConfigError(where, key, f"must be true or false, got {shown(value)}")
        return value
    if hint is str:
        if not isinstance(value, str):
            raise ConfigError(
                where, key, f"must be a string, got {type(value).__name__} {shown(value)}"
            )
        return value
    raise TypeError(f"unsupported config field type {hint!r} for {key}")  # a programming error
