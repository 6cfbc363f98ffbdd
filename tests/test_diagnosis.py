"""The diagnosis on the project's own demo traces (regression, not blind: the blind tests
on the independent generator are tests/test_diagnosis_rates.py), on real data that
no catalogue entry describes (BRFD: ``unknown``), degenerate traces, and the CLI's
contract."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gms_comp.app.cli import main
from gms_comp.app.commands.demo_trace import MAIN_PARAMETER, generate, scaled_table_trace
from gms_comp.errors import GmsCompError
from gms_comp.gms import GmsParams
from gms_comp.measured.diagnosis.run import diagnose
from gms_comp.measured.traces import Trace, write_trace
from gms_comp.physics.config import load_ball_config
from gms_comp.runtime.effects import ExtensionError, effect_from_dict
from gms_comp.tables.reduction import reduce_to_gms
from gms_comp.tables.table import GmsTable, read_table, write_table

# Relative tolerance on the main parameter of each effect, checked on seed 1 (over seeds
# 1-5 the worst errors were: dwell_time gamma 42 % on seed 2 (tau 0.011 s for 0.034 s,
# gamma with it along the ridge: the gain after the median dwell within 0.2 %; 16 % at
# most on the others), reversal_transient amplitude 12 % (the free GMS takes a little of
# the overshoot)).
TOLERANCE = {
    "offset": 0.05,
    "viscous": 0.1,
    "position_ripple": 0.02,
    "inertia": 0.05,
    "sensor_lowpass": 0.25,
    "stribeck": 0.2,
    "reversal_transient": 0.2,
    "dwell_time": 0.25,
    "drift": 0.25,
}


@pytest.mark.parametrize("seed", [1])  # the sweep over seeds is benchmarks/bench_diagnose.py
@pytest.mark.parametrize("hidden", sorted(TOLERANCE))
def test_hidden_effect_is_named_with_its_parameter(hidden: str, seed: int) -> None:
    g = generate(hidden, seed)
    result = diagnose(g.trace)
    assert result.effect == hidden
    assert g.hidden is not None
    key = MAIN_PARAMETER[hidden]
    truth = g.hidden.parameters()[key]
    assert result.to_json()["parameters"][key] == pytest.approx(truth, rel=TOLERANCE[hidden])
    assert result.gain > 0


@pytest.mark.parametrize("seed", [10, 11, 12])  # the false-positive rate over more seeds:
def test_no_effect_on_effect_free_traces(seed: int) -> None:  # benchmarks/bench_diagnose.py
    assert diagnose(generate("none", seed).trace).effect == "none"


def test_cli_writes_spec_keys_and_a_loadable_table(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    g = generate("offset", 3)
    trace_path = tmp_path / "trace.csv"
    write_trace(trace_path, g.trace)
    table = tmp_path / "ext.json"
    args = ["diagnose", str(trace_path), "--json", "--table", str(table), "--closed-loop"]
    assert main(args) == 0
    captured = capsys.readouterr()
    doc = json.loads(captured.out)  # --json: the JSON and nothing else on stdout
    assert f"wrote {table}" in captured.err
    for key in ("effect", "effects", "parameters", "baseline_rms_N", "extended_rms_N", "gain",
                "baseline", "phases"):  # fmt: skip
        assert key in doc
    assert doc["effect"] == "offset"
    assert doc["baseline"]["source"] == "free_nnls"  # no bearing config, no table given
    assert doc["gain"] == pytest.approx(1 - doc["extended_rms_N"] / doc["baseline_rms_N"])
    loaded = read_table(table)
    assert loaded.extensions[0].effect == "offset"
    # an axis with the offset: compensating it too lowers both the reversal peak and the RMS
    cl = doc["closed_loop"]
    for key in ("peak_reversal_error_m", "rms_error_m"):
        assert cl["extended"][key] < cl["baseline"][key]


def test_cli_bad_trace_is_one_line_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,position_m\n0,0\n")
    assert main(["diagnose", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "missing column 'force_N'" in err


def test_profile_writes_csv(tmp_path: Path) -> None:
    out = tmp_path / "p.csv"
    assert main(["profile", str(out)]) == 0
    header = out.read_text().splitlines()[0]
    assert header == "time_s,reference_position_m,velocity_m_s"


# A bearing whose friction is the ball model's, 1.3 x stronger, with presliding 0.7 x as
# long: the calibrated table baseline recovers both factors (over seeds 0-5 the errors were
# below 1 %: the level trades off a little against the slip level, their product is exact).
LEVEL_FACTOR, PRESLIDING_FACTOR, FACTOR_TOLERANCE = 1.3, 0.7, 0.03


@pytest.fixture(scope="module")
def ball_table() -> GmsTable:
    return reduce_to_gms(load_ball_config(None), 8)


def _scaled_ball_trace(table: GmsParams, seed: int) -> Trace:
    return scaled_table_trace(table, LEVEL_FACTOR, PRESLIDING_FACTOR, seed)


def test_table_baseline_recovers_level_and_presliding(ball_table: GmsTable) -> None:
    result = diagnose(_scaled_ball_trace(ball_table.params, 1), table=ball_table.params)
    b = result.baseline
    assert b["source"] == "table"
    assert b["level_factor"] == pytest.approx(LEVEL_FACTOR, rel=FACTOR_TOLERANCE)
    assert b["presliding_factor"] == pytest.approx(PRESLIDING_FACTOR, rel=FACTOR_TOLERANCE)
    assert b["slip_level_factor"] == pytest.approx(1.0, rel=FACTOR_TOLERANCE)
    # the calibrated truth fits as well as a free GMS, within 3 % (tighter than the 10 %
    # table_margin that chose it; both leave 1.4 x the noise: the 0.1 um position steps)
    assert b["table_heldout_rms_N"] <= 1.03 * b["free_nnls_heldout_rms_N"]


def test_unlike_gms_falls_back_to_free_nnls(ball_table: GmsTable) -> None:
    # sim.tracegen's truth: limits spread evenly over 0.3-20 um, no slip level - no
    # scaling of the ball model's elements has that virgin curve
    b = diagnose(generate("none", 10).trace, table=ball_table.params).baseline
    assert b["source"] == "free_nnls" and b["model"] == "free_nnls_gms"
    assert b["table_heldout_rms_N"] > b["free_nnls_heldout_rms_N"]


def test_cli_table_in_calibrates_the_table(
    tmp_path: Path, ball_table: GmsTable, capsys: pytest.CaptureFixture[str]
) -> None:
    trace_path, table_path = tmp_path / "t.csv", tmp_path / "ball.json"
    write_trace(trace_path, _scaled_ball_trace(ball_table.params, 2))
    write_table(table_path, ball_table)
    args = ["diagnose", str(trace_path), "--table-in", str(table_path), "--json"]
    assert main(args) == 0
    b = json.loads(capsys.readouterr().out)["baseline"]
    assert b["source"] == "table" and b["model"] == "table_gms"
    assert b["level_factor"] == pytest.approx(LEVEL_FACTOR, rel=FACTOR_TOLERANCE)


def test_summary_and_html_report(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    trace_path = tmp_path / "measured.csv"
    assert main(["demo-trace", str(trace_path), "--effect", "viscous", "--seed", "2"]) == 0
    assert "hidden effect: viscous" in capsys.readouterr().out
    report = tmp_path / "report"
    assert main(["diagnose", str(trace_path), "--report", str(report)]) == 0
    out = capsys.readouterr().out
    assert "cause: viscous (c = " in out and "N s/m" in out  # the parameter with its unit
    assert "where the baseline is wrong" in out and "gain:" in out
    for name in ("index.html", "extended.table.json"):
        assert (report / name).is_file()
        assert f"wrote {report / name}" in out
    assert sorted(p.name for p in report.iterdir()) == [
        "extended.table.json",
        "index.html",
        "manifest.json",
    ]
    page = (report / "index.html").read_text()
    # one self-contained file: every plot embedded, the zoomed views at a reversal and a
    # break-away among them; the intervals and what the trace rules out
    assert page.count('<img src="data:image/png;base64,') >= 5 and "viscous" in page
    assert "At a reversal" in page or "reversal" in page
    assert "95 % intervals" in page and "What this trace rules out" in page
    assert "measured.csv" in page and "gms-comp" in page


# Traces a diagnosis cannot use, and what the refusal must name.
def _degenerate(kind: str) -> Trace:
    t = np.arange(4000) * 1e-3
    x = 0.01 * np.sin(2 * np.pi * 0.5 * t) * (1 + 0.5 * np.sin(2 * np.pi * 0.13 * t))
    f = np.sign(np.gradient(x))
    if kind == "zero":
        f = 0 * t
    elif kind == "constant":
        f = np.full_like(t, 3.5)
    elif kind == "no_reversal":
        x = 0.02 * t
    elif kind == "one_speed":
        x = 0.01 * (2 / np.pi) * np.arcsin(np.sin(2 * np.pi * 0.5 * t))  # a triangle wave
    return Trace(source=f"{kind}.csv", time_s=t, position_m=x, force_N=f)


@pytest.mark.parametrize(
    ("kind", "says"),
    [("zero", "force is zero"), ("constant", "force is constant"),
     ("no_reversal", "reverses 0 time"), ("one_speed", "one speed only")],
)  # fmt: skip
def test_degenerate_trace_refused_in_one_line(
    kind: str, says: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / f"{kind}.csv"
    write_trace(path, _degenerate(kind))
    assert main(["diagnose", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and says in err and "record" in err


def test_unknown_extension_is_a_one_line_error() -> None:
    with pytest.raises(ExtensionError, match="unknown effect 'magic'") as caught:
        effect_from_dict({"effect": "magic", "parameters": {}})
    assert isinstance(caught.value, GmsCompError)  # the CLI prints one line, exit 2


BRFD = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "brfd_friction_damper"


def _brfd(name: str) -> Trace:
    path = BRFD / "harmonic" / f"{name}.npy"
    if not path.is_file():
        pytest.skip(f"BRFD data not found in {BRFD}")
    t, f, x, _v = np.load(path, allow_pickle=False).T
    return Trace(source=str(path), time_s=t, position_m=x, force_N=f)


@pytest.mark.slow
def test_self_energizing_damper_is_unknown_not_a_catalogue_name() -> None:
    # a self-energizing band damper: its loops depend on direction and stroke position,
    # which no catalogue effect describes (see its PROVENANCE.md)
    result = diagnose(_brfd("test5"), validation=_brfd("test6"))
    assert result.effect == "unknown"
    assert result.structure.description()
    assert result.extended_rms_N > 3 * result.noise_rms_N


def test_validation_trace_is_the_held_out_part() -> None:
    # a second record of the same machine: every sample of TRACE trains, TRACE2 scores
    train, held = generate("offset", 5, scale=0.25).trace, generate("offset", 5).trace
    result = diagnose(train, validation=held)
    assert result.effect == "offset"
    assert "validation_force_N" in result.series
    assert result.extended_rms_N < 0.5 * result.baseline_rms_N
