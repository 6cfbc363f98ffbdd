"""Property tests that follow the schema of every other input: tables, table extensions,
sweep files, replay models and the command line's numbers.

Each schema is read from the code that checks it (a table's :data:`NUMBERS` and
:data:`VECTORS`, each catalogue effect's parameter ranges, the sweep's bounds, the
baseline's fields, each option's range), values are drawn inside and outside it, and the
outcome is checked: inside accepted, outside an :class:`~gms_comp.errors.InputError`
naming the source and the field in one line, never another exception. Structural
mutations (missing keys, wrong containers, nesting, truncation, encodings) are refused
the same way. Draws are derandomized with fixed counts (:data:`SCHEMA`).
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gms_comp.app.cli import build_parser
from gms_comp.app.replay import MAX_AXIS_MASS_KG, baseline_axis_model, load_model
from gms_comp.app.sweep import MAX_SWEEP_ELEMENTS, load_sweep
from gms_comp.config import default_config_path, field_range
from gms_comp.errors import ConfigError, InputError, TableError
from gms_comp.gms import GmsParams
from gms_comp.runtime.effects import CATALOGUE, ExtensionError, effect_from_dict
from gms_comp.tables.table import (
    NULLABLE,
    NUMBERS,
    OPTIONAL,
    VECTORS,
    Fidelity,
    GmsTable,
    read_table,
    table_from_dict,
    table_to_dict,
)
from gms_comp.validation import MAX_SEED, MAX_WORKERS

SCHEMA = settings(
    derandomize=True,
    deadline=None,
    max_examples=40,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
HUGE = 10**400
NOT_NUMBERS = st.sampled_from(["1.0", True, None, [1.0], {"v": 1.0}])


def _one_line(err: Exception, source: str, key: str) -> None:
    text = str(err)
    assert "\n" not in text and text.startswith(source), text
    assert key in text, (key, text)


# --- tables --------------------------------------------------------------------------------

GOOD_TABLE = table_to_dict(
    GmsTable(
        GmsParams(
            stiffness_N_per_m=np.array([2e5, 5e4]), limit_N=np.array([0.2, 0.1]), slip_level=1.2
        ),
        source_config="c.toml",
        source_sha256="0" * 64,
        fidelity=Fidelity(0.01, 0.03),
    )
)


def _set(doc: dict[str, Any], key: str, value: Any) -> dict[str, Any]:
    out = copy.deepcopy(doc)
    obj = out
    *parents, name = key.split(".")
    for part in parents:
        obj = obj[part]
    obj[name] = value
    return out


def _positive_range(positive: bool, hi: float) -> st.SearchStrategy[float]:
    return st.floats(0.0, hi, exclude_min=positive, allow_infinity=False)


def _outside_range(positive: bool, hi: float) -> st.SearchStrategy[Any]:
    low = st.floats(max_value=0.0, exclude_max=not positive, allow_infinity=False)
    high = st.floats(min_value=hi, exclude_min=True) if math.isfinite(hi) else st.nothing()
    return st.one_of(low.filter(math.isfinite), high, st.sampled_from([math.nan, -math.inf, HUGE]))


@SCHEMA
@given(key=st.sampled_from(sorted(NUMBERS)), data=st.data())
def test_a_table_number_in_its_range_is_read_back(key: str, data: Any) -> None:
    value = data.draw(_positive_range(*NUMBERS[key]), label="value")
    table = table_from_dict(_set(GOOD_TABLE, key, value), "t.json")
    names = {"fidelity.rms_rel": "rms_rel", "fidelity.max_rel": "max_rel"}
    got = getattr(
        table.fidelity if key in names else table.params, names.get(key, key.split(".")[-1])
    )
    assert got == value or (key.endswith("transition_tail") and got == math.inf), (got, value)


@SCHEMA
@given(key=st.sampled_from(sorted(NUMBERS)), data=st.data())
def test_a_table_number_outside_its_range_is_refused(key: str, data: Any) -> None:
    strategy = _outside_range(*NUMBERS[key])
    if key not in NULLABLE:
        strategy = st.one_of(strategy, NOT_NUMBERS)
    value = data.draw(strategy, label="value")
    with pytest.raises(TableError) as refused:
        table_from_dict(_set(GOOD_TABLE, key, value), "t.json")
    _one_line(refused.value, "t.json", key)


@SCHEMA
@given(key=st.sampled_from(sorted(VECTORS)), data=st.data())
def test_a_table_element_outside_its_range_is_refused(key: str, data: Any) -> None:
    bad = data.draw(st.one_of(_outside_range(*VECTORS[key]), NOT_NUMBERS), label="entry")
    vector = list(GOOD_TABLE[key])
    vector[data.draw(st.integers(0, len(vector) - 1), label="at")] = bad
    with pytest.raises(TableError) as refused:
        table_from_dict(_set(GOOD_TABLE, key, vector), "t.json")
    _one_line(refused.value, "t.json", key)


def test_nullable_and_optional_table_fields() -> None:
    for key in NULLABLE:
        table_from_dict(_set(GOOD_TABLE, key, None), "t.json")
    for key in OPTIONAL:
        doc = copy.deepcopy(GOOD_TABLE)
        parent, name = key.rsplit(".", 1)
        del doc[parent][name]
        table_from_dict(doc, "t.json")


DROPPED = [k for k in GOOD_TABLE if k not in ("extensions", "extension_context")]
STRUCTURAL = [
    *((f"drop {k}", lambda d, k=k: {x: v for x, v in d.items() if x != k}) for k in DROPPED),
    ("elements 3", lambda d: d | {"elements": 3}),
    ("elements huge", lambda d: d | {"elements": HUGE}),
    ("elements float", lambda d: d | {"elements": 2.0}),
    ("level a list", lambda d: d | {"velocity_level": [1.2]}),
    ("source a string", lambda d: d | {"source": "c.toml"}),
    ("family a list", lambda d: d | {"load_family": [1.0]}),
    ("extensions a table", lambda d: d | {"extensions": {"a": 1}}),
    ("a list", lambda d: [d]),
]


@pytest.mark.parametrize("mutate", [pytest.param(m, id=n) for n, m in STRUCTURAL])
def test_a_structurally_broken_table_is_refused(mutate: Any) -> None:
    with pytest.raises(TableError) as refused:
        table_from_dict(mutate(copy.deepcopy(GOOD_TABLE)), "t.json")
    assert "\n" not in str(refused.value) and str(refused.value).startswith("t.json")


@SCHEMA
@given(
    cut=st.integers(1, 600),
    prefix=st.sampled_from([b"", b"\xef\xbb\xbf", b"[" * 40, b"\xff"]),
)
def test_a_truncated_or_encoded_table_file_is_refused_or_read(
    tmp_path: Path, cut: int, prefix: bytes
) -> None:
    text = json.dumps(GOOD_TABLE).encode()
    path = tmp_path / "t.json"
    path.write_bytes(prefix + text[: len(text) - cut])
    with pytest.raises(TableError) as refused:
        read_table(path)
    assert "\n" not in str(refused.value) and str(path) in str(refused.value)
    path.write_bytes(b"\xef\xbb\xbf" + text)  # a byte-order mark alone is read
    assert read_table(path).n_elements == 2


# --- table extensions: each effect's declared parameters -----------------------------------

PARAMETERS = [(name, f) for name, cls in CATALOGUE.items() for f in dataclasses.fields(cls)]


def _good_parameters(cls: type[Any]) -> dict[str, float]:
    out = {}
    for f in dataclasses.fields(cls):
        bounds = field_range(f)
        assert bounds is not None, f"{cls.name}.{f.name}: a parameter without a declared range"
        out[f.name] = bounds.hi  # the upper bound is inside every declared range here
    return out


@SCHEMA
@given(param=st.sampled_from(PARAMETERS), data=st.data())
def test_an_effect_parameter_inside_its_range_is_accepted(param: Any, data: Any) -> None:
    name, f = param
    bounds = field_range(f)
    assert bounds is not None
    if f.type in (int, "int"):
        value: float = data.draw(st.integers(math.ceil(bounds.lo), math.floor(bounds.hi)))
    else:
        value = data.draw(
            st.floats(bounds.lo, bounds.hi, exclude_min=bounds.lo_open, exclude_max=bounds.hi_open)
        )
    params = _good_parameters(CATALOGUE[name]) | {f.name: value}
    if name == "dwell_time" and f.name == "kept_through_turns":
        params[f.name] = float(value >= 0.5)  # 0 or 1: the effect's own rule
    effect = effect_from_dict({"effect": name, "parameters": params}, "t.json", "extensions.0")
    assert getattr(effect, f.name) == params[f.name]


@SCHEMA
@given(param=st.sampled_from(PARAMETERS), data=st.data())
def test_an_effect_parameter_outside_its_range_is_refused(param: Any, data: Any) -> None:
    name, f = param
    bounds = field_range(f)
    assert bounds is not None
    below = st.floats(max_value=bounds.lo, exclude_max=not bounds.lo_open, allow_infinity=False)
    above = st.floats(min_value=bounds.hi, exclude_min=not bounds.hi_open, allow_infinity=False)
    value = data.draw(st.one_of(below, above, st.sampled_from([math.nan, math.inf, HUGE, "1"])))
    params = _good_parameters(CATALOGUE[name]) | {f.name: value}
    with pytest.raises(ExtensionError) as refused:
        effect_from_dict({"effect": name, "parameters": params}, "t.json", "extensions.0")
    _one_line(refused.value, "t.json", f"extensions.0.parameters.{f.name}")


@pytest.mark.parametrize("name", sorted(CATALOGUE))
def test_an_effect_with_a_missing_or_unknown_parameter_is_refused(name: str) -> None:
    good = _good_parameters(CATALOGUE[name])
    for params in ({k: v for k, v in good.items() if k != next(iter(good))}, good | {"x": 1.0}):
        if params.keys() == good.keys():
            continue  # the left-out one was optional
        with pytest.raises(ExtensionError) as refused:
            effect_from_dict({"effect": name, "parameters": params}, "t.json", "extensions.0")
        _one_line(refused.value, "t.json", "extensions.0.parameters")


# --- sweep files ----------------------------------------------------------------------------


def _sweep(tmp_path: Path, elements: Any, axes: str = '"stand.ball_loads_N" = [50.0]') -> Path:
    path = tmp_path / "s.toml"
    value = json.dumps(elements) if not isinstance(elements, str) else f'"{elements}"'
    path.write_text(
        f'[sweep]\nbase_config = "{default_config_path()}"\nelements = {value}\n'
        f"[sweep.axes]\n{axes}\n"
    )
    return path


@SCHEMA
@given(elements=st.integers(1, MAX_SWEEP_ELEMENTS))
def test_sweep_elements_in_range_are_accepted(tmp_path: Path, elements: int) -> None:
    assert load_sweep(_sweep(tmp_path, elements)).elements == elements


@SCHEMA
@given(
    elements=st.one_of(
        st.integers(max_value=0),
        st.integers(min_value=MAX_SWEEP_ELEMENTS + 1),
        st.sampled_from([HUGE, 2.5, True, "4", [4]]),
    )
)
def test_sweep_elements_outside_are_refused(tmp_path: Path, elements: Any) -> None:
    path = _sweep(tmp_path, elements)
    with pytest.raises(ConfigError) as refused:
        load_sweep(path)
    _one_line(refused.value, str(path), "sweep.elements")


@pytest.mark.parametrize(
    ("axes", "key"),
    [
        ('"ball_loads_N" = [50.0]', "sweep.axes.ball_loads_N"),
        ('"stand.ball_loads_N" = []', "sweep.axes.stand.ball_loads_N"),
        ('"stand.ball_loads_N" = 50.0', "sweep.axes.stand.ball_loads_N"),
        ('"stand.no_such_key" = [1.0]', "sweep.axes.stand.no_such_key"),
        ('"stand.ball_loads_N" = [50.0]\n[scaleout]\nscheduler = "tcp://h:1"', "scaleout"),
        ('"stand.ball_loads_N" = [50.0]\n[other]\nx = 1', "sweep"),
    ],
)
def test_a_sweep_file_of_the_wrong_shape_is_refused(tmp_path: Path, axes: str, key: str) -> None:
    path = _sweep(tmp_path, 2, axes)
    with pytest.raises(ConfigError) as refused:
        load_sweep(path)
    _one_line(refused.value, str(path), key)


# --- replay models: a diagnosis JSON's baseline -------------------------------------------

BASELINE = {
    "breakaway_m": [1e-6, 1e-5],
    "limit_N": [2.0, 1.0],
    "slip_level": 1.2,
    "transition_velocity_m_s": 1e-4,
    "transition_exponent": 2.0,
    "mass_kg": 95.0,
}
BASELINE_NUMBERS = {
    "slip_level": NUMBERS["velocity_level.slip_level"],
    "transition_velocity_m_s": NUMBERS["velocity_level.transition_velocity_m_s"],
    "transition_exponent": NUMBERS["velocity_level.transition_exponent"],
    "mass_kg": (True, MAX_AXIS_MASS_KG),
}


@SCHEMA
@given(key=st.sampled_from(sorted(BASELINE_NUMBERS)), data=st.data())
def test_a_baseline_number_inside_is_replayed_and_outside_refused(key: str, data: Any) -> None:
    good = data.draw(_positive_range(*BASELINE_NUMBERS[key]), label="inside")
    axis = baseline_axis_model(BASELINE | {key: good}, "d.json")
    assert axis.mass_kg == (good if key == "mass_kg" else 95.0)
    bad = data.draw(st.one_of(_outside_range(*BASELINE_NUMBERS[key]), NOT_NUMBERS), label="out")
    with pytest.raises(InputError) as refused:
        baseline_axis_model(BASELINE | {key: bad}, "d.json")
    _one_line(refused.value, "d.json", f"baseline.{key}")


@pytest.mark.parametrize(
    "baseline",
    [
        BASELINE | {"breakaway_m": [1e-6]},  # fewer breakaways than limits
        BASELINE | {"breakaway_m": [0.0, 1e-5]},
        BASELINE | {"limit_N": [-1.0, 1.0]},
        BASELINE | {"limit_N": [0.0, 0.0]},
        BASELINE | {"breakaway_m": [1e-6] * 2000, "limit_N": [1.0] * 2000},
        {k: v for k, v in BASELINE.items() if k != "mass_kg"},
    ],
)
def test_a_baseline_of_the_wrong_shape_is_refused(baseline: dict[str, Any]) -> None:
    with pytest.raises(InputError) as refused:
        baseline_axis_model(baseline, "d.json")
    _one_line(refused.value, "d.json", "baseline.")


def test_a_deep_or_huge_model_file_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "m.json"
    for text in ("[" * 100_000 + "]" * 100_000, '{"baseline": {"mass_kg": 1' + "0" * 400 + "}}"):
        path.write_text(text)
        with pytest.raises(InputError) as refused:
            load_model(path)
        assert "\n" not in str(refused.value) and str(path) in str(refused.value)


# --- command-line numbers ---------------------------------------------------------------------

OPTIONS = [  # (argv before the option, option, integer?, lo, hi, lo open?)
    (["stream"], "--seed", True, 0, MAX_SEED, False),
    (["demo-trace", "x.csv"], "--seed", True, 0, MAX_SEED, False),
    (["stream"], "--duration", False, 0.0, 3600.0, True),
    (["sweep", "SWEEP", "--serial"], "--workers", True, 1, MAX_WORKERS, False),
    (["table", "-o", "t.json"], "--elements", True, 1, 1024, False),
    (["profile", "p.csv"], "--sample-rate-hz", False, 10.0, 1e5, False),
    (["replay", "SWEEP"], "--reversal-deadband", False, 0.0, 1e-2, False),
]


def _parse(tmp_path: Path, argv: list[str]) -> int:
    (tmp_path / "s.toml").touch()
    words = [str(tmp_path / "s.toml") if w == "SWEEP" else w for w in argv]
    words = [str(tmp_path / w) if w.endswith((".csv", ".json")) else w for w in words]
    try:
        build_parser(words[0]).parse_args(words)
    except SystemExit as done:
        return int(done.code or 0)
    return 0


@SCHEMA
@given(option=st.sampled_from(OPTIONS), data=st.data())
def test_a_command_line_number_is_bounded_when_parsed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], option: Any, data: Any
) -> None:
    before, flag, integer, lo, hi, lo_open = option
    inside = st.integers(lo, hi) if integer else st.floats(lo, hi, exclude_min=lo_open)
    good = data.draw(inside, label="inside")
    assert _parse(tmp_path, [*before, flag, repr(good)]) == 0
    below: st.SearchStrategy[Any]
    above: st.SearchStrategy[Any]
    if integer:
        below, above = st.integers(max_value=lo - 1), st.integers(min_value=hi + 1)
    else:
        below = st.floats(max_value=lo, exclude_max=not lo_open)
        above = st.floats(min_value=hi, exclude_min=True)
    words = ["nan", "inf", "-inf", "1" + "0" * 400, "2.5" if integer else "x", ""]
    outside = st.one_of(below.map(repr), above.map(repr), st.sampled_from(words))
    bad = data.draw(outside, label="outside")
    capsys.readouterr()
    assert _parse(tmp_path, [*before, flag, bad]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and flag in err[0], err
