"""The compensator on a live bus: the simulated machine, following it, commissioning it.

Expectations come from outside the code under test: the hidden effect's parameters as
configured in ``[machine]`` (the diagnosis must find them), the reversal errors of the
axis without feedforward (what any useful feedforward must beat), and the protocol's
figures (one answer per SYNC, nothing foreign applied).
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import time
from pathlib import Path
from typing import Any, cast

import pytest

from firmware_bridge.profiles.cia402.drive import Cia402Drive
from firmware_bridge.profiles.cia402.tx import Cia402Tx
from firmware_bridge.settings import CanConfig
from gms_comp.app.cli import main
from gms_comp.app.commands.commission import summary
from gms_comp.app.commands.diagnose import extended_table
from gms_comp.app.live.commission import commission, physics_table
from gms_comp.app.live.follow import Follower, follow
from gms_comp.app.live.machine import machine_on_bus, scenario_program
from gms_comp.app.live.recording import (
    drive_and_record,
    profile_targets,
    to_trace,
    write_recording,
)
from gms_comp.app.live.report import write_report
from gms_comp.config import default_config_path
from gms_comp.measured.diagnosis.run import DiagnosisConfig, diagnose
from gms_comp.measured.traces import load_trace
from gms_comp.runtime.observer import FrictionObserver
from sim.machine import CspAxis, load_machine
from sim.plant import ScaledFriction
from sim.scenarios import ball_set_friction
from sim.strategies import calibrate

_channels = itertools.count()
RIPPLE = {"amplitude_N": 2.0, "wavelength_m": 2e-3, "phase_rad": 0.4}


def machine_config(tmp_path: Path, effect: str, **parameters: float) -> Path:
    lines = [f'effect = "{effect}"', *(f"{k} = {v!r}" for k, v in parameters.items())]
    path = tmp_path / f"machine_{effect}.toml"
    path.write_text(default_config_path().read_text() + "\n[machine]\n" + "\n".join(lines) + "\n")
    return path


@pytest.mark.slow
def test_commissioning_finds_the_hidden_ripple_and_the_feedforward_gains(tmp_path: Path) -> None:
    """Stepped on a built-in machine drive: the whole commissioning, exact and repeatable."""
    path = machine_config(tmp_path, "position_ripple", **RIPPLE)
    machine = load_machine(path)
    cfg = dataclasses.replace(CanConfig(), channel=f"test-live-{next(_channels)}")

    def drive(c: CanConfig, bus: object) -> Cia402Drive:
        return Cia402Drive(c, bus, CspAxis(machine, c.cycle_period_s))  # type: ignore[arg-type]

    result = commission(cfg, machine.scenario, lambda r: extended_table(r, path), 0.25,
                        drive=drive)  # fmt: skip
    doc = result.to_json()
    found = {e["effect"]: e["parameters"] for e in doc["diagnosis"]["effects"]}
    assert "position_ripple" in found
    assert found["position_ripple"]["wavelength_m"] == pytest.approx(2e-3, rel=0.1)
    assert found["position_ripple"]["amplitude_N"] == pytest.approx(2.0, rel=0.1)
    v = doc["verification"]
    assert set(v) == {"none", "coulomb_viscous", "table", "extended", "calibrated"}
    assert v["extended"]["peak_reversal_error_m"] <= 0.2 * v["none"]["peak_reversal_error_m"]
    assert v["extended"]["rms_error_m"] < v["table"]["rms_error_m"]  # the ripple, fed forward
    # the deployed table is the tables' best in the reversal test
    best = min(v[k]["peak_reversal_error_m"] for k in ("table", "extended", "calibrated"))
    assert v[doc["deployed"]]["peak_reversal_error_m"] == best
    # what the user reads: the cause with its parameters, the errors in um, what was deployed
    text = summary(doc)
    assert "cause: position_ripple: position_ripple (amplitude = " in text
    assert f"deployed: {doc['deployed']}" in text and text.count(" um / ") == len(v)
    page = write_report(result, doc, tmp_path / "report", cfg.cycle_period_s)
    html = next(p for p in page if p.suffix == ".html").read_text()
    assert "position_ripple" in html and f"Deployed: {doc['deployed']}" in html
    # the Coulomb level fitted from the bus recording (the mass's m a taken out) against the
    # one calibrated on the ball model itself at two speeds, as `simulate` does
    c = machine.scenario.scenario
    truth = ScaledFriction(
        ball_set_friction(machine.scenario.ball), machine.scenario.plant.ball_set_count
    )
    v1, v2 = c.calibration_velocities_m_s
    calibrated = calibrate(truth, c.calibration_travel_m, (v1, v2))
    assert doc["coulomb_viscous"]["coulomb_N"] == pytest.approx(calibrated.coulomb_N, rel=0.1)
    runs = doc["can"]["runs"]
    assert set(runs) == {"identification", *v}
    assert all(r["frames_sent"] > 0 and r["stale_or_corrupt_applied"] == 0 for r in runs.values())
    assert doc["can"]["stale_or_corrupt_applied"] == 0  # the built-in drive counts it


HIDDEN = {
    "position_ripple": (RIPPLE, "wavelength_m"),
    "reversal_transient": ({"amplitude_N": 4.0, "length_m": 4e-5}, "amplitude_N"),
    "viscous": ({"c_Ns_per_m": 150.0}, "c_Ns_per_m"),
    "none": ({}, ""),
}


@pytest.mark.slow
@pytest.mark.parametrize("effect", list(HIDDEN))
def test_the_recording_of_a_machine_names_what_it_hides_and_nothing_else(
    tmp_path: Path, effect: str
) -> None:
    """Stepped on a built-in machine drive: the identification profile recorded over the
    bus and diagnosed on the physics table names the hidden effect alone, its main
    parameter within 10 % (a table calibrated without a viscous slope took it into its
    slip level, 1.12x, and a Stribeck fall was named beside it to take it back)."""
    parameters, main = HIDDEN[effect]
    path = machine_config(tmp_path, effect, **parameters)
    machine = load_machine(path)
    cfg = dataclasses.replace(CanConfig(), channel=f"test-live-{next(_channels)}")

    def drive(c: CanConfig, bus: object) -> Cia402Drive:
        return Cia402Drive(c, bus, CspAxis(machine, c.cycle_period_s))  # type: ignore[arg-type]

    s = machine.scenario
    recording, _ = drive_and_record(cfg, profile_targets(cfg.cycle_period_s, 0.25).tolist(),
                                    drive=drive)  # fmt: skip
    csv = tmp_path / "identification.csv"
    write_recording(to_trace(recording, cfg, s.plant, "test"), csv)
    result = diagnose(load_trace(csv), "drive", None, DiagnosisConfig(), physics_table(s).params)
    found = {e["effect"]: e["parameters"] for e in result.to_json()["effects"]}
    if effect == "none":
        assert found == {}
        return
    assert list(found) == [effect]
    assert found[effect][main] == pytest.approx(parameters[main], rel=0.1)


@pytest.mark.slow
def test_commissioning_compensates_a_hidden_reversal_transient_over_the_bus_and_in_the_drive(
    tmp_path: Path,
) -> None:
    """Stepped on a built-in machine drive: a reversal transient (4 N over 40 um) is named
    with its amplitude, and the extended table's peak reversal error is at most 0.2x that
    without feedforward and 0.8x the physics table's, over the bus (the feedforward sent
    with the target it goes with: a cycle early, 149 nm against 447 nm without) and with
    each table run by the drive's own observer at its servo rate; the deployed table is
    the best in the drive."""
    path = machine_config(tmp_path, "reversal_transient", amplitude_N=4.0, length_m=4e-5)
    machine = load_machine(path)
    cfg = dataclasses.replace(CanConfig(), channel=f"test-live-{next(_channels)}")

    def drive(c: CanConfig, bus: object) -> Cia402Drive:
        return Cia402Drive(c, bus, CspAxis(machine, c.cycle_period_s))  # type: ignore[arg-type]

    result = commission(cfg, machine.scenario, lambda r: extended_table(r, path), 0.25,
                        drive=drive, in_drive=True)  # fmt: skip
    doc = result.to_json()
    found = {e["effect"]: e["parameters"] for e in doc["diagnosis"]["effects"]}
    assert found["reversal_transient"]["amplitude_N"] == pytest.approx(4.0, rel=0.1)
    peak = {k: v["peak_reversal_error_m"] for k, v in doc["verification"].items()}
    assert {"table_in_drive", "extended_in_drive", "calibrated_in_drive"} <= set(peak)
    assert peak["extended"] <= 0.2 * peak["none"]
    assert peak["extended"] <= 0.8 * peak["table"]
    assert peak["extended_in_drive"] <= 0.2 * peak["none"]
    assert peak["extended_in_drive"] <= 0.8 * peak["table_in_drive"]
    assert doc["deployed_in_drive"]
    best = min(peak[f"{k}_in_drive"] for k in ("table", "extended", "calibrated"))
    assert peak[f"{doc['deployed']}_in_drive"] == best
    assert "in the drive" in summary(doc)


@pytest.mark.slow
def test_run_follows_the_machines_nc_and_answers_every_sync() -> None:
    """In real time: the machine with its NC on a virtual channel, the compensator following
    it with the physics table (no foreign or stale frame can be applied: one session)."""
    machine = load_machine()
    cfg = dataclasses.replace(CanConfig(), channel=f"test-live-{next(_channels)}")
    program = scenario_program(machine, cfg.cycle_period_s)[:2500]

    s = machine.scenario
    observer = FrictionObserver(physics_table(s), s.plant.force_constant_N_per_A,
                                cfg.cycle_period_s, 1.0, s.compensator)  # fmt: skip
    with machine_on_bus(machine, cfg, program) as node:
        time.sleep(0.1)
        report = follow(cfg, observer, "reference", 1, 2.0)
        status = node.status()
    assert report["syncs_seen"] >= report["frames_sent"] > 500
    assert report["sync_to_sent_p99_s"] > 0 and 0 < report["answered_within_cycle"] <= 1
    assert status["frames_applied"] > 0
    assert status["frames_rejected"]["foreign"] == 0
    # the same program without feedforward: the friction's following error, which the
    # table's feedforward must lower (the error is the position against the target it
    # followed, not against the next one: a cycle's travel would be 20 um here)
    cfg = dataclasses.replace(cfg, channel=f"test-live-{next(_channels)}")
    with machine_on_bus(machine, cfg, program):
        time.sleep(0.1)
        bare = follow(cfg, None, "reference", 1, 2.0)
    assert bare["tracking_rms_error_m"] < 1e-6
    # a loop that kept its cycle lowers the error with the table; on a loaded host (one
    # answer in a hundred late, frames missed, the drive falling back) it may not: the
    # table measured 15-40 nm against 71 nm when within the cycle for 99.7-99.95 % of
    # SYNCs, 114 nm at 98.9 %
    if report["answered_within_cycle"] >= 0.995:
        assert report["tracking_rms_error_m"] < bare["tracking_rms_error_m"]


def test_commission_refuses_a_bus_with_an_nc(capsys: pytest.CaptureFixture[str]) -> None:
    machine = load_machine()
    cfg = dataclasses.replace(CanConfig(), channel=f"test-live-{next(_channels)}")
    with machine_on_bus(machine, cfg, scenario_program(machine, 1e-3)):
        code = main(["commission", "--channel", cfg.channel])
    err = capsys.readouterr().err
    assert code == 2 and "an NC produces SYNC" in err and err.count("\n") == 1


def test_machine_runs_for_its_duration_and_reports(capsys: pytest.CaptureFixture[str]) -> None:
    channel = f"test-live-{next(_channels)}"
    code = main(["machine", "--channel", channel, "--duration", "0.3", "--json"])
    captured = capsys.readouterr()
    status = json.loads(captured.out)
    assert code == 0 and "ready" in captured.err
    assert status["stopped_by"] == "duration" and status["state"] == "switch_on_disabled"


def test_the_follower_reads_speed_over_the_syncs_since_its_last_input() -> None:
    """A stall of the NC (SYNCs not seen) is no jump in speed: the observer gets the
    distance over the time since the last input, and the position looked ahead by it."""
    seen: list[tuple[float, float]] = []

    class Recording:
        def step(self, position_m: float, velocity_m_s: float) -> float:
            seen.append((position_m, velocity_m_s))
            return 0.0

    tx = Cia402Tx(CanConfig(sync_master=False))
    follower = Follower(tx, cast(Any, Recording()), "reference", 1, 1e-3)
    speed = 0.02  # m/s
    for slot in (0, 1, 2, 30, 31):  # 27 SYNCs missed between 2 and 30
        tx.observed.target_m = speed * slot * 1e-3
        tx.observed.counts["nc"] += 1
        follower(slot * 1e-3)
    assert [v for _, v in seen[1:]] == pytest.approx([speed] * 4)
    assert [x for x, _ in seen] == pytest.approx(
        [speed * (k + 1) * 1e-3 for k in (-1, 1, 2, 30, 31)]
    )
