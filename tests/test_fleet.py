"""Fleet diagnosis: one row per trace, error rows, recurring effects, Dask = serial."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from gms_comp.app.cli import main
from gms_comp.app.commands.demo_trace import generate, scaled_table_trace
from gms_comp.app.fleet import (
    FleetJob,
    diagnose_fleet,
    format_table,
    recurring_effects,
    report_names,
)
from gms_comp.app.scaleout import dask_client
from gms_comp.measured.traces import write_trace
from gms_comp.physics.config import load_ball_config
from gms_comp.tables.reduction import reduce_to_gms
from gms_comp.tables.table import write_table

HIDDEN = [("offset", 1), ("offset", 2), ("none", 3)]


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> tuple[list[FleetJob], list[Any]]:
    folder = tmp_path_factory.mktemp("fleet")
    jobs, truths = [], []
    for name, seed in HIDDEN:
        generated = generate(name, seed, scale=0.1)
        path = folder / f"{name}_{seed}.csv"
        write_trace(path, generated.trace)
        jobs.append(FleetJob(str(path)))
        truths.append(generated.hidden)
    bad = folder / "broken.csv"
    bad.write_text("time_s,position_m,force_N\n0.0,0.0,1.0\n0.001,nan,1.0\n")
    jobs.append(FleetJob(str(bad)))
    return jobs, truths


@pytest.fixture(scope="module")
def serial(fleet: tuple[list[FleetJob], list[Any]]) -> dict[str, Any]:
    return diagnose_fleet(fleet[0])


def test_each_trace_gets_its_row_and_a_bad_one_an_error(
    fleet: tuple[list[FleetJob], list[Any]], serial: dict[str, Any]
) -> None:
    jobs, truths = fleet
    rows = serial["traces"]
    assert [r["trace"] for r in rows] == [j.trace for j in jobs]
    assert [r["status"] for r in rows] == ["ok", "ok", "ok", "error"]
    assert "broken.csv" in rows[3]["error"] and "TraceError" in rows[3]["error"]
    assert [r["effect"] for r in rows[:3]] == ["offset", "offset", "none"]
    for row, truth in zip(rows[:2], truths[:2], strict=True):
        assert row["parameters"]["offset_N"] == pytest.approx(truth.offset_N, rel=0.05)
        assert row["gain"] > 0.5


def test_recurring_effects_name_what_the_fleet_shares(serial: dict[str, Any]) -> None:
    (offset,) = serial["recurring_effects"]
    assert offset["effect"] == "offset" and offset["count"] == 2
    assert offset["share"] == pytest.approx(2 / 4)
    values = sorted(r["parameters"]["offset_N"] for r in serial["traces"][:2])
    assert values[0] <= offset["median_parameters"]["offset_N"] <= values[1]


def test_a_trace_s_caveat_is_printed_under_its_row(serial: dict[str, Any]) -> None:
    # the fleet's own traces move both ways at the same speeds: no caveat in any row
    assert all(r["caveats"] == [] for r in serial["traces"] if r["status"] == "ok")
    said = "speed and direction go together on this trace"
    caveat = {"kind": "speed_direction", "effects": ["stribeck"], "text": said}
    row = {
        "trace": "slow_back.csv",
        "status": "ok",
        "effect": "direction_asymmetry",
        "parameters": {"c_diff_Ns_per_m": 40.0},
        "gain": 0.5,
        "caveats": [caveat],
    }
    lines = format_table({"traces": [row], "recurring_effects": []}).splitlines()
    assert lines[1].startswith("slow_back.csv") and lines[2].split() == ["caveat:", *said.split()]


def test_recurring_effects_ignore_singletons_and_none() -> None:
    rows: list[dict[str, Any]] = [
        {"status": "ok", "effect": "viscous", "parameters": {"c": 1.0}, "gain": 0.2, "trace": "a"},
        {"status": "ok", "effect": "none", "parameters": {}, "gain": 0.0, "trace": "b"},
        {"status": "ok", "effect": "none", "parameters": {}, "gain": 0.0, "trace": "c"},
        {"status": "error", "error": "x", "trace": "d"},
    ]
    assert recurring_effects(rows) == []


def test_local_cluster_gives_the_serial_rows(
    fleet: tuple[list[FleetJob], list[Any]], serial: dict[str, Any]
) -> None:
    with dask_client(n_workers=2) as client:
        parallel = diagnose_fleet(fleet[0], client=client)
    assert parallel == serial


def test_diagnose_command_takes_many_traces(
    fleet: tuple[list[FleetJob], list[Any]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    paths = [job.trace for job in fleet[0]]
    code = main(["diagnose", *paths[2:], "--serial", "--json"])
    assert code == 1  # one trace failed: the run says so, the others are reported
    summary = json.loads(capsys.readouterr().out)
    assert [r["status"] for r in summary["traces"]] == ["ok", "error"]
    assert summary["traces"][1]["trace"].endswith("broken.csv")


def test_report_folder_names_are_unique_and_contained() -> None:
    traces = ["a/run.csv", "b/run.csv", "...csv", "../../etc/x.csv", ".hidden.csv", "B/RUN.csv"]
    names = report_names(traces)
    assert len(set(n.lower() for n in names)) == len(names)  # also on a case-blind disk
    for name in names:
        assert name and "/" not in name and "\\" not in name and not name.startswith(".")
        assert Path(name).name == name and ".." not in name


def test_single_trace_options_are_refused_for_a_fleet(
    fleet: tuple[list[FleetJob], list[Any]], capsys: pytest.CaptureFixture[str]
) -> None:
    paths = [job.trace for job in fleet[0][:2]]
    assert main(["diagnose", *paths, "--serial", "--validate", paths[0]]) == 2
    assert "--validate applies to a single trace" in capsys.readouterr().err


def test_fleet_calibrates_one_catalogue_table_per_trace(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--table-in across a fleet: a machine that matches the table is calibrated on it,
    one that does not falls back to the free GMS."""
    table = reduce_to_gms(load_ball_config(None), 8)
    table_path = tmp_path / "guide.json"
    write_table(table_path, table)
    like, unlike = tmp_path / "like.csv", tmp_path / "unlike.csv"
    write_trace(like, scaled_table_trace(table.params, 1.3, 0.7, seed=4))
    write_trace(unlike, generate("none", 10).trace)
    args = ["diagnose", str(like), str(unlike), "--table-in", str(table_path), "--serial"]
    assert main([*args, "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["traces"]
    assert [r["baseline_source"] for r in rows] == ["table", "free_nnls"]
