"""Property tests that follow the config schema, not a list of cases.

Every field of every config section declares its type and, for a number, its range (the
``in_range``/``positive`` metadata, read by :func:`gms_comp.config.field_range`). For each
field these tests draw values from the declared range and from outside it (below, above,
NaN, infinities, integers of hundreds of digits, wrong types, arrays too long or empty)
and check what the validation layer does with them:

- inside: the section is accepted with that value, or refused by the section's own
  cross-field check (its ``problems()``, computed here on the dataclass directly: the
  documented refusal);
- outside: a :class:`~gms_comp.errors.ConfigError` naming the file and ``section.field``,
  one line; never another exception.

The same holds through a TOML file and ``gms-comp config`` in-process (exit 0 or 2, one
line on stderr), and for structural mutations of a config file (byte-order mark, other
encodings, truncation, nesting, stray bytes). Example counts are fixed and the draws
derandomized (:data:`SCHEMA`), so the suite runs the same examples every time.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gms_comp.app.cli import main
from gms_comp.app.commands.config import SECTIONS, all_sections
from gms_comp.config import (
    default_config_path,
    field_range,
    is_section,
    parse_section,
    read_toml,
)
from gms_comp.errors import ConfigError

SCHEMA = settings(
    derandomize=True,
    deadline=None,
    max_examples=30,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
BASE = read_toml(default_config_path())
WHERE = "cfg.toml"
# every section and sub-section (``diagnosis.selection``) with its dataclass
CLASSES = dict(all_sections())
FIELDS = [
    pytest.param(section, f.name, id=f"{section}.{f.name}")
    for section, cls in CLASSES.items()
    for f in dataclasses.fields(cls)
    if not is_section(typing.get_type_hints(cls)[f.name])
]
HUGE = 10**400


def _field(section: str, name: str) -> tuple[type[Any], dataclasses.Field[Any], Any]:
    cls = CLASSES[section]
    f = next(f for f in dataclasses.fields(cls) if f.name == name)
    return cls, f, typing.get_type_hints(cls)[name]


def _number_inside(hint: Any, f: dataclasses.Field[Any]) -> st.SearchStrategy[Any]:
    bounds = field_range(f)
    assert bounds is not None, f"{f.name}: a number without a declared range"
    if hint is int:
        lo = math.floor(bounds.lo) + (1 if bounds.lo_open and bounds.lo.is_integer() else 0)
        lo = max(lo, math.ceil(bounds.lo))
        hi = math.floor(bounds.hi) - (1 if bounds.hi_open and bounds.hi.is_integer() else 0)
        return st.integers(lo, hi)
    floats = st.floats(bounds.lo, bounds.hi, exclude_min=bounds.lo_open, exclude_max=bounds.hi_open)
    lo_int, hi_int = math.ceil(bounds.lo), math.floor(bounds.hi)
    ints = st.integers(lo_int + bounds.lo_open * (lo_int == bounds.lo), hi_int)
    return st.one_of(floats, ints.filter(bounds.contains)) if lo_int <= hi_int else floats


def inside(section: str, name: str) -> st.SearchStrategy[Any]:
    """A value of the field's declared type and range (as a TOML document holds it)."""
    _cls, f, hint = _field(section, name)
    origin = typing.get_origin(hint)
    if origin is typing.Literal:
        return st.sampled_from(typing.get_args(hint))
    if hint is bool:
        return st.booleans()
    if hint is str:
        if section == "can" and name == "profile":
            from firmware_bridge.profiles import PROFILES

            return st.sampled_from(sorted(PROFILES))
        return st.text(max_size=20)
    if origin is tuple:
        cap = min((field_range(f) or _no_range(f)).max_items or 8, 8)
        return st.lists(_number_inside(float, f), min_size=1, max_size=cap)
    return _number_inside(hint, f)


def _no_range(f: dataclasses.Field[Any]) -> Any:
    raise AssertionError(f"{f.name}: an array of numbers without a declared range")


WRONG_TYPES = st.sampled_from(["text", True, {"a": 1}, [[1.0]]])


def outside(section: str, name: str) -> st.SearchStrategy[Any]:
    """A value the field must refuse: out of range, not finite, too big, wrong type."""
    _cls, f, hint = _field(section, name)
    origin = typing.get_origin(hint)
    if origin is typing.Literal:
        choices = typing.get_args(hint)
        return st.one_of(st.text(max_size=8).filter(lambda v: v not in choices), WRONG_TYPES)
    if hint is bool:
        return st.one_of(
            st.sampled_from(["yes", 1, 0.0]), WRONG_TYPES.filter(lambda v: v is not True)
        )
    if hint is str:
        if section == "can" and name == "profile":
            from firmware_bridge.profiles import PROFILES

            return st.text(max_size=8).filter(lambda v: v not in PROFILES)
        return st.sampled_from([1, 2.5, True, ["x"], {"a": "b"}])
    bounds = field_range(f)
    assert bounds is not None
    below = st.floats(max_value=bounds.lo, exclude_max=not bounds.lo_open).filter(math.isfinite)
    above = st.floats(min_value=bounds.hi, exclude_min=not bounds.hi_open).filter(math.isfinite)
    special = st.sampled_from([math.nan, math.inf, -math.inf, HUGE, -HUGE])
    bad_number = st.one_of(below, above, special)
    if hint is int:
        bad_number = st.one_of(
            st.integers(max_value=math.ceil(bounds.lo) - 1),
            st.integers(min_value=math.floor(bounds.hi) + 1),
            st.sampled_from([HUGE, -HUGE, 2.5]),
        )
    if origin is tuple:
        good = _number_inside(float, f)
        lists = [
            st.just([]),
            st.lists(good, max_size=3).flatmap(lambda xs: bad_number.map(lambda b: [*xs, b])),
            st.just("text"),
            st.just([["nested"]]),
        ]
        if bounds.max_items is not None:
            lists.append(good.map(lambda v: [v] * (bounds.max_items + 1)))  # type: ignore[operator]
        return st.one_of(*lists)
    return st.one_of(bad_number, WRONG_TYPES)


def _doc(section: str, name: str, value: Any) -> dict[str, Any]:
    doc = copy.deepcopy(BASE)
    table = doc
    for part in section.split("."):
        table = table.setdefault(part, {})
    table[name] = value
    return doc


def _parse(doc: dict[str, Any], section: str) -> Any:
    """``section`` (``a.b``: the top section ``a`` parsed, then its ``.b``) as parsed."""
    top, *inner = section.split(".")
    obj = parse_section(doc, WHERE, top, SECTIONS[top])
    for part in inner:
        obj = getattr(obj, part)
    return obj


def _replaced(obj: Any, path: list[str], name: str, value: Any) -> list[tuple[str, Any]]:
    """``obj`` with ``path``'s field ``name`` set to ``value``: each rebuilt section from
    the innermost out, with its dotted prefix below ``obj``."""
    if not path:
        return [("", dataclasses.replace(obj, **{name: value}))]
    rebuilt = _replaced(getattr(obj, path[0]), path[1:], name, value)
    inner = rebuilt[-1][1]
    here = dataclasses.replace(obj, **{path[0]: inner})
    return [(f"{path[0]}." + p if p else f"{path[0]}.", o) for p, o in rebuilt] + [("", here)]


def _expected_problem(section: str, name: str, value: Any) -> str | None:
    """The section's own cross-field refusal of ``value`` (computed on the dataclass, not
    through the parser), or None."""
    _cls, _f, hint = _field(section, name)
    top, *inner = section.split(".")
    base = parse_section(BASE, WHERE, top, SECTIONS[top])
    if hint is float:
        value = float(value)
    elif typing.get_origin(hint) is tuple:
        value = tuple(float(v) for v in value)
    for prefix, obj in _replaced(base, inner, name, value):  # innermost first, as parsed
        problems = obj.problems() if hasattr(obj, "problems") else []
        if problems:
            return f"{top}.{prefix}{problems[0][0]}"
    return None


@pytest.mark.parametrize(("section", "name"), FIELDS)
@SCHEMA
@given(data=st.data())
def test_a_value_in_its_declared_range_is_accepted(section: str, name: str, data: Any) -> None:
    value = data.draw(inside(section, name), label="value")
    expected = _expected_problem(section, name, value)
    if expected is None:
        got = getattr(_parse(_doc(section, name, value), section), name)
        assert got == (tuple(value) if isinstance(value, list) else value)
    else:
        with pytest.raises(ConfigError) as refused:
            _parse(_doc(section, name, value), section)
        assert refused.value.key == expected


@pytest.mark.parametrize(("section", "name"), FIELDS)
@SCHEMA
@given(data=st.data())
def test_a_value_outside_its_range_or_type_is_refused_in_one_line(
    section: str, name: str, data: Any
) -> None:
    value = data.draw(outside(section, name), label="value")
    with pytest.raises(ConfigError) as refused:
        _parse(_doc(section, name, value), section)
    err = refused.value
    key = f"{section}.{name}"
    assert err.path == WHERE and (err.key == key or err.key.startswith(f"{key}[")), err
    assert "\n" not in str(err) and len(str(err)) < 400, str(err)


# --- through a file and the command line ---------------------------------------------------

ALL_FIELDS = [
    (section, f.name)
    for section, cls in CLASSES.items()
    for f in dataclasses.fields(cls)
    if not is_section(typing.get_type_hints(cls)[f.name])
]
# Whole-config checks (every command's loader, run by `config`): the keys they name.
WHOLE_CONFIG_KEYS = ("scenario", "compensator", "stand.ball_loads_N", "table.family_loads_N",
                     "plant.current_limit_A", "scaleout.")  # fmt: skip


def _run_config(tmp_path: Path, doc: dict[str, Any], capsys: Any) -> tuple[int, list[str]]:
    path = tmp_path / "c.toml"
    path.write_text(tomli_w.dumps(doc), encoding="utf-8")
    code = main(["config", str(path)])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    return code, err


@settings(SCHEMA, max_examples=80)
@given(field=st.sampled_from(ALL_FIELDS), data=st.data())
def test_config_command_refuses_out_of_range_values_from_a_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], field: tuple[str, str], data: Any
) -> None:
    section, name = field
    value = data.draw(outside(section, name), label="value")
    try:
        doc = _doc(section, name, value)
        tomli_w.dumps(doc)
    except (TypeError, ValueError):  # TOML cannot hold it (null, a mixed array): no file
        return
    code, err = _run_config(tmp_path, doc, capsys)
    assert code == 2 and len(err) == 1, err
    assert str(tmp_path / "c.toml") in err[0] and f"{section}.{name}" in err[0], err[0]


@settings(SCHEMA, max_examples=80)
@given(field=st.sampled_from(ALL_FIELDS), data=st.data())
def test_config_command_accepts_in_range_values_or_names_the_check(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], field: tuple[str, str], data: Any
) -> None:
    section, name = field
    value = data.draw(inside(section, name), label="value")
    code, err = _run_config(tmp_path, _doc(section, name, value), capsys)
    assert code in (0, 2) and len(err) == code // 2, err
    if code == 2:  # a documented refusal: the section's cross-field rule or a whole-config one
        own = _expected_problem(section, name, value)
        named = [own] if own else []
        assert any(k in err[0] for k in (*named, *WHOLE_CONFIG_KEYS)), err[0]


MUTATIONS: list[tuple[str, Callable[[bytes, int], bytes]]] = [
    ("bom", lambda b, _i: b"\xef\xbb\xbf" + b),
    ("latin-1", lambda b, i: b[:i] + "# für\n".encode("latin-1") + b[i:]),
    ("utf-16", lambda b, _i: b.decode().encode("utf-16")),
    ("truncated", lambda b, i: b[:i]),
    ("nul", lambda b, i: b[:i] + b"\x00" + b[i:]),
    ("nested", lambda b, _i: b + b"\n[table]\nfamily_loads_N = " + b"[" * 40 + b"]" * 40),
    ("section-value", lambda b, _i: b"bearing = 1\n" + b),
    ("duplicate", lambda b, _i: b + b"\n[bearing]\nball_radius_m = 3e-3\n"),
    ("stray", lambda b, i: b[:i] + b']]{="\n' + b[i:]),
]


@SCHEMA
@given(mutation=st.sampled_from(MUTATIONS), at=st.integers(0, 1500))
def test_a_mutated_config_file_is_read_or_refused_in_one_line(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    mutation: tuple[str, Callable[[bytes, int], bytes]],
    at: int,
) -> None:
    name, mutate = mutation
    good = default_config_path().read_bytes()
    path = tmp_path / "m.toml"
    path.write_bytes(mutate(good, min(at, len(good))))
    code = main(["config", str(path)])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code in (0, 2) and len(err) == code // 2, (name, err)
    if name in ("bom",):
        assert code == 0, err  # an editor's byte-order mark is read
    if name in ("utf-16", "nul", "nested", "section-value", "duplicate"):
        assert code == 2 and str(path) in err[0], (name, err)


def test_every_number_in_every_section_has_a_finite_declared_range() -> None:
    """The schema is complete: no config number is unbounded (no duration, rate, count or
    seed read from a file can overflow, hang or allocate without bound)."""
    for section, cls in CLASSES.items():
        hints = typing.get_type_hints(cls)
        for f in dataclasses.fields(cls):
            hint = hints[f.name]
            if hint in (int, float) or typing.get_origin(hint) is tuple:
                bounds = field_range(f)
                assert bounds is not None, f"{section}.{f.name} has no declared range"
                assert math.isfinite(bounds.lo) and math.isfinite(bounds.hi), f.name
