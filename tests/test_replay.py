"""The replay of a measured closed-loop run (issue 14) against the EMPS benchmark's numbers.

The reference rows are the benchmark paper's (Janot, Gautier, Brunot 2019, §3.5,
relative errors of Simulation_EMPS.m with the IDIM-LS parameters) and the position error
RMS of ../shared/data/emps/simulate_closed_loop.py; the replay must give them to three
significant digits.
"""

from __future__ import annotations

import contextlib
import json
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from gms_comp.app import replay, replay_compensation
from gms_comp.app.cli import main
from gms_comp.gms import GmsParams, simulate
from gms_comp.measured.traces import Trace, write_trace
from gms_comp.runtime.effects import Context, apply_extensions, effect_from_dict
from gms_comp.tables.table import Extension, Fidelity, GmsTable
from gms_comp.validation import InputError
from sim.link import DirectLink
from sim.position_loop import PositionLoop, RigidAxisModel, friction_along, simulate_loop


def _emps_folder() -> Path | None:
    """../shared/data/emps from the checkout (or a worktree beside it)."""
    for parent in Path(__file__).resolve().parents:
        candidate = parent / "shared" / "data" / "emps"
        if candidate.is_dir():
            return candidate
    return None


EMPS = _emps_folder()
needs_emps = pytest.mark.skipif(EMPS is None, reason="EMPS data (../shared/data/emps) absent")

# record: position %, velocity %, force % (paper §3.5), q error RMS um (issue 14), and
# acceleration % of the Python re-statement (PROVENANCE.md; the paper's 8.6036 / 19.8152
# differ in the third digit, its Simulink ode45 against the re-statement's RK4)
PUBLISHED = {
    "DATA_EMPS.mat": (0.013752, 0.22911, 5.848, 20.50, 8.5944),
    "DATA_EMPS_PULSES.mat": (0.0080248, 0.47888, 8.9409, 12.00, 19.833),
}


def _same_to_3_digits(value: float, published: float) -> bool:
    half_unit = 0.5 * 10 ** (math.floor(math.log10(abs(published))) - 2)
    return abs(value - published) <= half_unit


@needs_emps
@pytest.mark.parametrize("name", sorted(PUBLISHED))
def test_reference_rows_reproduced(name: str) -> None:
    assert EMPS is not None
    record = replay.load_record(EMPS / name)
    scores = replay.replay_scores(record, replay.replay(record, replay.reference_model()))
    rel = scores["relative_error_pct"]
    q_rms_um = scores["position_error_rms_m"] * 1e6
    got = (rel["position"], rel["velocity"], rel["force"], q_rms_um, rel["acceleration"])
    for value, published in zip(got, PUBLISHED[name], strict=True):
        assert _same_to_3_digits(value, published), (value, published)


@needs_emps
def test_record_loop_is_the_records() -> None:
    assert EMPS is not None
    record = replay.load_record(EMPS / "DATA_EMPS_PULSES.mat")
    loop = record.loop
    assert (loop.position_gain_per_s, loop.velocity_gain_per_m_s) == (160.18, 243.45)
    assert loop.drive_gain_N == pytest.approx(35.15065188248547)
    assert record.disturbance is not None and set(np.unique(record.disturbance[1])) == {0, 5}


def test_offset_force_gives_the_p_loop_steady_error() -> None:
    # At rest against a constant force F0 the loop holds e = F0 / (gtau kv kp).
    loop = PositionLoop(1e-3, 50.0, 20.0, 10.0, 100.0)
    model = RigidAxisModel(mass_kg=5.0, offset_N=3.0)
    run = simulate_loop(loop, model, np.zeros(4000))
    assert run.position_m[-1] == pytest.approx(-3.0 / (10.0 * 20.0 * 50.0), rel=1e-6)


def test_disturbance_after_saturation_acts_like_a_force() -> None:
    # 0.3 command units of disturbance on a saturated-free loop equal a -3 N offset
    loop = PositionLoop(1e-3, 50.0, 20.0, 10.0, 100.0)
    pushed = simulate_loop(
        loop, RigidAxisModel(5.0), np.zeros(3000), disturbance=(np.zeros(1), np.full(1, 0.3))
    )
    offset = simulate_loop(loop, RigidAxisModel(5.0, offset_N=-3.0), np.zeros(3000))
    np.testing.assert_allclose(pushed.position_m, offset.position_m, atol=1e-12)


def _extended_table() -> GmsTable:
    """A table with every extension the rigid axis simulates (EMPS-like numbers)."""
    params = GmsParams(np.array([6e5, 2e4, 4e3]), np.array([19.0, 1.5, 0.9]))
    extensions = (
        Extension("viscous", {"c_Ns_per_m": 190.0}),
        Extension("direction_asymmetry", {"c_diff_Ns_per_m": -80.0}),
        Extension("reversal_transient", {"amplitude_N": 20.0, "length_m": 4e-5}),
        Extension(
            "position_ripple", {"amplitude_N": 0.9, "wavelength_m": 2.5e-3, "phase_rad": 0.3}
        ),
        Extension("stribeck", {"ratio": 0.7, "v_s_m_per_s": 0.02}),
        Extension("offset", {"offset_N": -3.0}),
        Extension("inertia", {"mass_kg": 95.0}),
        Extension("drive_lag", {"lag_s": 7e-4}),
    )
    return GmsTable(params, "test", "0" * 64, Fidelity(0.0, 0.0), extensions=extensions)


def test_plant_friction_is_the_runtime_effects_of_the_table() -> None:
    # The compiled plant and the catalogue's batch effects on the GMS force must agree
    # along any motion (here two strokes with reversals, at 1 kHz).
    table = _extended_table()
    model = replay.table_axis_model(table, 1.0, "test", reversal_deadband_m=0.0)
    t = np.arange(4000) * 1e-3
    q = 0.01 * (1 - np.cos(2 * np.pi * t / 2.0))
    v = np.gradient(q, 1e-3)
    gms_force = simulate(table.params, q, v)[0]
    physical = [
        e
        for e in (
            effect_from_dict({"effect": x.effect, "parameters": x.parameters})
            for x in table.extensions
        )
        if not e.measurement_only
    ]
    expected = apply_extensions(physical, Context.along(t, q, v, np.gradient(v, 1e-3), gms_force))
    np.testing.assert_allclose(friction_along(model, q, v), expected, atol=1e-9)
    assert model.mass_kg == 95.0 and model.drive_lag_s == 0.0  # lag: measurement chain


def test_table_with_an_unsimulated_effect_is_refused() -> None:
    table = GmsTable(
        GmsParams(np.array([1e5]), np.array([10.0])), "test", "0" * 64, Fidelity(0.0, 0.0),
        extensions=(Extension("drift", {"kappa": 0.1, "tau_s": 10.0}),),
    )  # fmt: skip
    with pytest.raises(InputError, match="drift"):
        replay.table_axis_model(table, 1.0, "t.json")


def test_lagged_drive_settles_to_the_same_steady_error() -> None:
    # A first-order lag in the drive changes the transient, not the statics.
    loop = PositionLoop(1e-3, 50.0, 20.0, 10.0, 100.0)
    lagged = simulate_loop(
        loop, RigidAxisModel(5.0, offset_N=3.0, drive_lag_s=2e-3), np.zeros(4000)
    )
    assert lagged.position_m[-1] == pytest.approx(-3.0 / (10.0 * 20.0 * 50.0), rel=1e-6)
    assert lagged.axis_force_N[-1] == pytest.approx(3.0, rel=1e-6)


@needs_emps
def test_replay_cli_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert EMPS is not None
    plot = tmp_path / "replay.png"
    code = main(
        [
            "replay",
            str(EMPS / "DATA_EMPS.mat"),
            "--loop",
            "benchmark",
            "--json",
            "--plot",
            str(plot),
        ]
    )
    captured = capsys.readouterr()
    doc = json.loads(captured.out)
    assert code == 0 and plot.stat().st_size > 0
    assert set(doc["relative_error_pct"]) == {"position", "velocity", "acceleration", "force"}
    assert doc["relative_error_pct"] == doc["reference"]["relative_error_pct"]  # default model
    assert doc["position_error_rms_m"] == pytest.approx(20.5e-6, abs=0.05e-6)
    assert set(doc["phases"]["model"]) >= {"reversal", "standstill", "constant_speed_pos"}
    assert f"wrote {plot}" in captured.err


@needs_emps
def test_compensation_on_the_replayed_axis(tmp_path: Path) -> None:
    # With the table as the plant's friction and the table as feedforward, the friction's
    # share of the following error shrinks below the uncompensated axis's.
    assert EMPS is not None
    record = replay.load_record(EMPS / "DATA_EMPS.mat")
    table = _extended_table()
    plant = replay.table_axis_model(table, 1.0, "test")

    @contextlib.contextmanager
    def direct() -> Iterator[DirectLink]:
        yield DirectLink()

    ideal, runs = replay_compensation.compensation(record, plant, table, direct)
    scores = {name: s for name, (_, s) in runs.items()}
    assert set(scores) == {"none", "reference", "gms"}
    assert scores["gms"]["rms_friction_error_m"] < 0.2 * scores["none"]["rms_friction_error_m"]
    # the share is the frictionless axis's position minus this one's
    none_run = runs["none"][0]
    share = ideal.position_m - none_run.position_m
    assert scores["none"]["rms_friction_error_m"] == pytest.approx(np.sqrt(np.mean(share**2)))


def test_replay_of_its_own_run_is_exact(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # A CSV record made by the loop itself, its gains given in [controller], replays to
    # (almost) zero error with the same model: the round trip through file and config.
    loop = PositionLoop(1e-3, 100.0, 50.0, 20.0, 10.0)
    model = replay.reference_model(
        {"M_kg": 20.0, "Fv_Ns_per_m": 30.0, "Fc_N": 5.0, "offset_N": 0.5}
    )
    t = np.arange(3000) * 1e-3
    qg = 0.005 * (1 - np.cos(2 * np.pi * t / 1.5))
    made = simulate_loop(loop, model, qg)
    write_trace(
        tmp_path / "run.csv",
        Trace("run", t, made.position_m, loop.drive_gain_N * made.command, reference_position_m=qg),
    )
    config = tmp_path / "loop.toml"
    config.write_text(
        "[controller]\nstructure = 'position_velocity'\nservo_rate_Hz = 1000.0\n"
        "velocity_filter_Hz = 100.0\nkp_per_s = 100.0\nkv_command_s_per_m = 50.0\n"
        "drive_gain_N_per_command = 20.0\n"
    )
    record = replay.load_record(
        tmp_path / "run.csv",
        replay.parse_controller(config),
        time_base="data",
    )
    scores = replay.replay_scores(record, replay.replay(record, model))
    assert scores["position_error_max_m"] < 1e-9
    assert scores["relative_error_pct"]["force"] < 1e-4


@needs_emps
def test_replay_refuses_a_file_that_is_no_model(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert EMPS is not None
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "something else"}')
    assert main(["replay", str(EMPS / "DATA_EMPS.mat"), "--model", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "neither a GMS table nor a diagnose JSON" in err


@pytest.mark.parametrize("delay", [0, 1, 2])
def test_command_acts_after_its_delay(delay: int) -> None:
    # From rest at 0 m with the reference at 1 mm, the controller's first output is
    # kv kp qg (no velocity yet); it reaches the drive ``delay`` cycles later, nothing
    # before (delay 0 used to act as 1: the ring was read before it was written).
    loop = PositionLoop(1e-3, 50.0, 20.0, 10.0, 100.0, delay_cycles=delay)
    run = simulate_loop(loop, RigidAxisModel(5.0), np.full(5, 1e-3))
    assert np.all(run.command[:delay] == 0.0)
    assert run.command[delay] == pytest.approx(20.0 * 50.0 * 1e-3)


@needs_emps
@pytest.mark.parametrize("name", sorted(PUBLISHED))
def test_record_timing_is_the_records(name: str) -> None:
    # The recorded command is the control law of the same sample's position (less the
    # PULSES record's pulses), not of the previous one's ...
    assert EMPS is not None
    raw = replay.load_record(EMPS / name, time_base="data", loop="record")
    loop, q = raw.loop, raw.position_m
    assert loop.delay_cycles == 0
    assert replay.load_record(EMPS / name).loop.delay_cycles == 1  # the benchmark's
    qf = np.convolve(q, loop.velocity_fir)[: q.size]
    speed = np.concatenate([[0.0], np.diff(qf)]) / loop.period_s
    law = loop.velocity_gain_per_m_s * (loop.position_gain_per_s * (raw.reference_m - q) - speed)
    pulses = 0.0 if raw.disturbance is None else raw.disturbance[1]
    command = raw.force_N / loop.drive_gain_N - pulses
    same, previous = (
        float(np.sqrt(np.mean((command[2 + d :] - law[2 : law.size - d]) ** 2))) for d in (0, 1)
    )
    assert same < 0.5 * previous
    # ... and the benchmark's own model replays the measured force closer when the
    # command acts in the cycle it is computed in.
    record = replay.load_record(EMPS / name, loop="record")
    force = {
        timing: replay.replay_scores(r, replay.replay(r, replay.reference_model()))[
            "relative_error_pct"
        ]["force"]
        for timing, r in (("benchmark", replay.load_record(EMPS / name)), ("record", record))
    }
    assert force["record"] < 0.8 * force["benchmark"]


def test_drive_lag_is_in_the_plant_on_the_records_loop_only() -> None:
    table = _extended_table()
    assert replay.table_axis_model(table, 1.0, "t").drive_lag_s == 0.0
    held = replay.table_axis_model(table, 1.0, "t", held_period_s=1e-3)
    assert held.drive_lag_s == pytest.approx(7e-4 - 0.5e-3)


@needs_emps
def test_replay_cli_on_the_records_loop(capsys: pytest.CaptureFixture[str]) -> None:
    assert EMPS is not None
    assert main(["replay", str(EMPS / "DATA_EMPS.mat"), "--json"]) == 0  # the default loop
    doc = json.loads(capsys.readouterr().out)
    assert (doc["loop"], doc["time_base"]) == ("record", "data")
    assert (doc["command_delay_cycles"], doc["drive_lag_s"]) == (0, 0.0)
    assert doc["relative_error_pct"]["force"] < 5.0  # 5.85 % on the benchmark's loop
    # the paper's rows beside, and the reference model replayed on the paper's timing
    paper, ours = doc["published_reference"], doc["reference_benchmark_timing"]
    assert _same_to_3_digits(ours["relative_error_pct"]["force"], paper["force"])
    assert ours["position_error_rms_m"] == pytest.approx(paper["position_error_rms_m"], abs=5e-8)


@needs_emps
def test_a_held_command_reads_as_half_a_cycle_of_drive_lag() -> None:
    # Why the record's loop takes half a cycle off a table's drive lag: the replay of
    # DATA_EMPS's reference on the benchmark's model with no drive lag at all (the
    # command held over its cycle, positions on the encoder's grid), diagnosed as a
    # measured drive-force run, gets a drive lag of about half a cycle.
    from gms_comp.measured.diagnosis.run import diagnose

    assert EMPS is not None
    record = replay.load_record(EMPS / "DATA_EMPS.mat", time_base="data", loop="record")
    run = replay.replay(record, replay.reference_model())
    q = np.round(run.position_m / 5e-8) * 5e-8
    force = record.loop.drive_gain_N * run.command
    trace = Trace("replayed", record.time_s - record.time_s[0], q, force)
    result = diagnose(trace, force_kind="drive")
    lags = [e.lag_s for e in result.extensions if e.name == "drive_lag"]  # type: ignore[attr-defined]
    assert len(lags) == 1 and 0.3e-3 < lags[0] < 0.6e-3, lags


@needs_emps
@pytest.mark.slow
def test_extended_model_from_data_emps_meets_the_targets(tmp_path: Path) -> None:
    # Issue 14's targets, end to end as a user runs them: the table that `diagnose --table`
    # identifies on DATA_EMPS alone, replayed on the record's timing; PULSES is the
    # cross-test. Force error <= 4.0 % / 6.0 %, position error RMS below the benchmark's
    # reference model on the same timing, on both records.
    assert EMPS is not None
    table = tmp_path / "extended.json"
    assert main(["diagnose", str(EMPS / "DATA_EMPS.mat"), "--table", str(table)]) == 0
    for name, force_target in (("DATA_EMPS.mat", 4.0), ("DATA_EMPS_PULSES.mat", 6.0)):
        record = replay.load_record(EMPS / name, time_base="data", loop="record")
        choice = replay.load_model(table, held_period_s=record.loop.period_s)
        model = replay.replay_scores(record, replay.replay(record, choice.axis))
        ref = replay.replay_scores(record, replay.replay(record, replay.reference_model()))
        assert model["relative_error_pct"]["force"] <= force_target, name
        assert model["position_error_rms_m"] < ref["position_error_rms_m"], name


@needs_emps
@pytest.mark.slow
def test_diagnosis_of_emps_holds_the_benchmark_figures(capsys: pytest.CaptureFixture[str]) -> None:
    # Issue 15's guard: blind diagnosis of DATA_EMPS validated on PULSES, as the README
    # runs it, at or below 2.5 % (training) and 4.0 % (cross-test), the causes named.
    assert EMPS is not None
    args = ["diagnose", str(EMPS / "DATA_EMPS.mat"), "--validate",
            str(EMPS / "DATA_EMPS_PULSES.mat"), "--json"]  # fmt: skip
    assert main(args) == 0
    doc = json.loads(capsys.readouterr().out)
    train, cross = doc["relative_error_pct"], doc["validation_relative_error_pct"]
    assert train["extended"] <= 2.5 and cross["extended"] <= 4.0
    # better than the benchmark's own IDIM-LS reference on both records
    assert train["extended"] < train["reference_idim_ls"]
    assert cross["extended"] < cross["reference_idim_ls"]
    assert doc["effect"] not in ("none", "unknown")


def test_a_diagnose_json_s_baseline_keeps_its_velocity_level(tmp_path: Path) -> None:
    """The replayed baseline is the one the diagnosis fitted: its transition speed,
    exponent, tail and law, not only C_v (an older JSON without them gets the defaults,
    a null tail is the exponential, a law that is not a boolean is refused)."""
    baseline = {"breakaway_m": [1e-6, 1e-5], "limit_N": [2.0, 0.0], "slip_level": 1.2,
                "transition_velocity_m_s": 3e-4, "transition_exponent": 1.5,
                "transition_tail": 1.0, "limit_follows_level": True, "mass_kg": 95.0}  # fmt: skip
    path = tmp_path / "diagnosis.json"
    path.write_text(json.dumps({"baseline": baseline}))
    gms = replay.load_model(path).axis.gms
    assert gms is not None
    assert (gms.slip_level, gms.transition_velocity_m_s) == (1.2, 3e-4)
    assert (gms.transition_exponent, gms.transition_tail) == (1.5, 1.0)
    assert gms.limit_follows_level is True
    np.testing.assert_allclose(gms.limit_N, [2.0])
    path.write_text(json.dumps({"baseline": baseline | {"transition_tail": None}}))
    null_tail = replay.load_model(path).axis.gms
    assert null_tail is not None and null_tail.transition_tail == math.inf
    path.write_text(json.dumps({"baseline": baseline | {"limit_follows_level": "yes"}}))
    with pytest.raises(InputError, match="limit_follows_level"):
        replay.load_model(path)
    for key in ("transition_velocity_m_s", "transition_exponent", "transition_tail",
                "limit_follows_level"):  # fmt: skip
        del baseline[key]
    path.write_text(json.dumps({"baseline": baseline}))
    old = replay.load_model(path).axis.gms
    assert old is not None
    assert (old.transition_velocity_m_s, old.transition_exponent) == (1e-4, 2.0)
    assert old.transition_tail == math.inf and old.limit_follows_level is False
