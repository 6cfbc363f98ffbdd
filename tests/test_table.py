"""Table files: exact round trips, and every defect refused with file and field named."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gms_comp import __version__
from gms_comp.errors import GmsCompError, TableError
from gms_comp.gms import GmsParams
from gms_comp.physics.config import load_ball_config
from gms_comp.physics.transient import BallSetFriction
from gms_comp.tables.table import (
    Extension,
    Fidelity,
    GmsTable,
    LoadFamily,
    Scaling,
    read_table,
    table_to_dict,
    write_table,
)

positive = st.floats(1e-9, 1e9, allow_nan=False, allow_infinity=False)


def make_table(
    k: list[float], w: list[float], rate: float = math.inf, with_family: bool = True
) -> GmsTable:
    family = LoadFamily(
        np.array([25.0, 50.0]), np.array([k, [2 * v for v in k]]), np.array([w, [2 * v for v in w]])
    )
    return GmsTable(
        params=GmsParams(
            np.array(k),
            np.array(w),
            slip_level=1.2,
            attraction_rate_per_s=rate,
            viscous_Ns_per_m=0.5,
        ),
        source_config="configs/table1.toml",
        source_sha256="ab" * 32,
        fidelity=Fidelity(rms_rel=0.01, max_rel=0.05),
        load_family=family if with_family else None,
        extensions=(Extension("stribeck", {"velocity_m_s": 1e-3, "ratio": 1.1}),),
        scaled_by=Scaling(40.0, (50.0, 48.5)) if with_family else None,
    )


def assert_same(a: GmsTable, b: GmsTable) -> None:
    assert table_to_dict(a) == table_to_dict(b)
    np.testing.assert_array_equal(a.params.stiffness_N_per_m, b.params.stiffness_N_per_m)
    np.testing.assert_array_equal(a.params.limit_N, b.params.limit_N)


@settings(
    max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    st.lists(st.tuples(positive, st.floats(0, 1e3)), min_size=1, max_size=40),
    st.one_of(st.just(math.inf), positive),
    st.booleans(),
)
def test_round_trip_is_exact(
    tmp_path: Path, kw: list[tuple[float, float]], rate: float, with_family: bool
) -> None:
    table = make_table([k for k, _ in kw], [w for _, w in kw], rate, with_family)
    path = tmp_path / "t.json"
    write_table(path, table)
    back = read_table(path)
    assert_same(table, back)
    assert back.version == __version__
    assert back.params.attraction_rate_per_s == rate
    assert back.extensions == table.extensions
    assert back.scaled_by == table.scaled_by


def test_load_family_interpolates_linearly_and_clamps() -> None:
    family = make_table([1e6, 2e6], [0.1, 0.2]).load_family
    assert family is not None
    k, w = family.elements_at(37.5)
    np.testing.assert_allclose(k, [1.5e6, 3e6])
    np.testing.assert_allclose(w, [0.15, 0.3])
    np.testing.assert_allclose(family.elements_at(100.0)[1], [0.2, 0.4])


def write_doc(tmp_path: Path, doc: Any) -> Path:
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    return path


def good_doc() -> dict[str, Any]:
    return table_to_dict(make_table([1e6, 2e6], [0.1, 0.2]))


def set_in(doc: dict[str, Any], dotted: str, value: Any) -> None:
    *parents, last = dotted.split(".")
    target: Any = doc
    for p in parents:
        target = target[int(p)] if isinstance(target, list) else target[p]
    if isinstance(target, list):
        target[int(last)] = value
    else:
        target[last] = value


@pytest.mark.parametrize(
    ("dotted", "value", "field"),
    [
        ("format_version", 5, "format_version"),
        ("format_version", 3, "format_version"),
        ("scaled_by.ball_sets", -1.0, "scaled_by.ball_sets"),
        ("scaled_by.ball_loads_N", [], "scaled_by.ball_loads_N"),
        ("scaled_by", {"ball_sets": 40.0}, "scaled_by.ball_loads_N"),
        ("gms_comp_version", "7.0.0", "gms_comp_version"),
        ("format", "something-else", "format"),
        ("elements", 3, "stiffness_N_per_m"),
        ("stiffness_N_per_m.1", -5.0, "stiffness_N_per_m[1]"),
        ("limit_N.0", -0.1, "limit_N[0]"),
        ("limit_N.0", "0.1", "limit_N[0]"),
        ("viscous_Ns_per_m", -1.0, "viscous_Ns_per_m"),
        ("velocity_level.slip_level", 0.0, "velocity_level.slip_level"),
        ("velocity_level.transition_tail", -1.0, "velocity_level.transition_tail"),
        ("velocity_level.transition_tail", "rational", "velocity_level.transition_tail"),
        ("velocity_level.transition_tail", 1e300, "velocity_level.transition_tail"),
        ("velocity_level.limit_follows_level", "yes", "velocity_level.limit_follows_level"),
        ("velocity_level.limit_follows_level", 1, "velocity_level.limit_follows_level"),
        ("fidelity.rms_rel", None, "fidelity.rms_rel"),
        ("source.sha256", "xyz", "source.sha256"),
        ("units.force", "kN", "units"),
        ("load_family.normal_load_N", [50.0, 25.0], "load_family.normal_load_N"),
        ("load_family.limit_N.1.0", -1.0, "load_family.limit_N[1][0]"),
        ("extensions.0.parameters.ratio", "big", "extensions.0.parameters.ratio"),
        ("extensions.0.effect", "no spaces", "extensions.0.effect"),
    ],
)
def test_bad_values_are_refused_naming_file_and_field(
    tmp_path: Path, dotted: str, value: Any, field: str
) -> None:
    doc = good_doc()
    set_in(doc, dotted, value)
    path = write_doc(tmp_path, doc)
    with pytest.raises(TableError) as err:
        read_table(path)
    assert str(path) in str(err.value)
    assert field in str(err.value)


def test_nan_literal_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "nan.json"
    path.write_text(
        json.dumps(good_doc()).replace('"viscous_Ns_per_m": 0.5', '"viscous_Ns_per_m": NaN')
    )
    with pytest.raises(TableError, match="NaN"):
        read_table(path)


@pytest.mark.parametrize("tail", [1.0, 3.5, math.inf])
def test_the_level_s_tail_round_trips_and_absent_is_exponential(
    tmp_path: Path, tail: float
) -> None:
    """A finite tail is written as a number and read back; the exponential (inf) as
    null; a table written before the tail existed (no key) reads as the exponential."""
    table = make_table([1e6, 2e5], [0.1, 0.2])
    table = dataclasses.replace(
        table, params=dataclasses.replace(table.params, transition_tail=tail)
    )
    path = tmp_path / "t.json"
    write_table(path, table)
    doc = json.loads(path.read_text())
    assert doc["velocity_level"]["transition_tail"] == (None if math.isinf(tail) else tail)
    # version 4: every reader of it knows the tail (a version-1 reader refuses the table)
    assert doc["format_version"] == 4
    assert read_table(path).params.transition_tail == tail
    del doc["velocity_level"]["transition_tail"]
    assert read_table(write_doc(tmp_path, doc)).params.transition_tail == math.inf


def test_a_limit_that_follows_the_level_round_trips(tmp_path: Path) -> None:
    """The law is written and read back (version 4, which a reader of 1 to 3 refuses
    rather than run the seed's law); without the key it is the seed's law;
    a table with it and a finite attraction rate is refused (the law has no attraction)."""
    table = make_table([1e6, 2e5], [0.1, 0.2])
    law = dataclasses.replace(table.params, slip_level=1.2, limit_follows_level=True)
    path = tmp_path / "t.json"
    write_table(path, dataclasses.replace(table, params=law))
    doc = json.loads(path.read_text())
    assert doc["velocity_level"]["limit_follows_level"] is True
    assert doc["format_version"] == 4
    assert read_table(path).params.limit_follows_level is True
    tailed = dataclasses.replace(law, transition_tail=1.0)
    write_table(path, dataclasses.replace(table, params=tailed))
    assert read_table(path).params.transition_tail == 1.0
    del doc["velocity_level"]["limit_follows_level"]
    assert read_table(write_doc(tmp_path, doc)).params.limit_follows_level is False
    doc["velocity_level"]["limit_follows_level"] = True
    doc["attraction_rate_per_s"] = 100.0
    with pytest.raises(TableError, match="limit_follows_level"):
        read_table(write_doc(tmp_path, doc))


def test_missing_key_is_named(tmp_path: Path) -> None:
    doc = good_doc()
    del doc["fidelity"]["max_rel"]
    with pytest.raises(TableError, match=r"fidelity\.max_rel: missing"):
        read_table(write_doc(tmp_path, doc))


@pytest.mark.parametrize("cut", [0.1, 0.5, 0.99])
def test_truncated_file_is_refused(tmp_path: Path, cut: float) -> None:
    path = tmp_path / "t.json"
    write_table(path, make_table([1e6, 2e6], [0.1, 0.2]))
    text = path.read_text()
    path.write_text(text[: int(len(text) * cut)])
    with pytest.raises(TableError, match="truncated"):
        read_table(path)


def test_errors_belong_to_the_project_root_and_to_value_error(tmp_path: Path) -> None:
    with pytest.raises(GmsCompError):
        read_table(tmp_path / "absent.json")
    with pytest.raises(ValueError):
        read_table(write_doc(tmp_path, [1, 2, 3]))


def test_table_command_writes_a_readable_table(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from gms_comp.app.cli import main

    out = tmp_path / "t8.json"
    assert main(["table", "-o", str(out), "--elements", "8", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    table = read_table(out)
    assert summary["elements"] == table.n_elements == 8
    # the whole axis: [plant] ball_set_count (40) copies of the stand's ball set
    assert table.scaled_by == Scaling(40.0, (50.0, 50.0, 50.0, 50.0))
    one_set = BallSetFriction(load_ball_config())  # its steady sliding force, independently
    one_set.reset()
    sliding_N = [one_set.step(x, 0.01) for x in np.linspace(0.0, 1e-3, 400)][-1]
    assert summary["sliding_force_N"] == pytest.approx(40 * sliding_N, rel=0.03)
    assert summary["fidelity"]["rms_rel"] == table.fidelity.rms_rel <= 0.02
    assert summary["fidelity"]["max_rel"] >= summary["fidelity"]["rms_rel"]
    assert main(["table", str(tmp_path / "absent.toml"), "-o", str(out)]) == 2


CONTEXT = {"standstill_speed_m_s": 2e-4, "reversal_deadband_m": 1e-7, "rest_band_m": 1.5e-7}


def test_extension_context_round_trips_and_absent_means_the_defaults(tmp_path: Path) -> None:
    table = dataclasses.replace(make_table([1e6], [0.1]), extension_context=CONTEXT)
    write_table(tmp_path / "t.json", table)
    assert read_table(tmp_path / "t.json").extension_context == CONTEXT
    doc = good_doc()
    del doc["extension_context"]  # a table written before the key existed
    assert read_table(write_doc(tmp_path, doc)).extension_context is None


@pytest.mark.parametrize(
    ("value", "field"),
    [
        ([1.0], "extension_context"),
        ({**CONTEXT, "rest_band_m": -1e-9}, "extension_context.rest_band_m"),
        ({**CONTEXT, "standstill_speed_m_s": 5.0}, "extension_context.standstill_speed_m_s"),
        ({**CONTEXT, "band": 1.0}, "extension_context.band"),
        ({"rest_band_m": 1e-7}, "extension_context.standstill_speed_m_s"),
    ],
)
def test_bad_extension_context_is_refused(tmp_path: Path, value: Any, field: str) -> None:
    doc = good_doc()
    doc["extension_context"] = value
    path = write_doc(tmp_path, doc)
    with pytest.raises(TableError) as err:
        read_table(path)
    assert str(path) in str(err.value) and field in str(err.value)
