"""One meaning of a table: a diagnosed table deployed with ``[compensator] table_path``
runs as the whole axis's friction, never multiplied by ``[plant] ball_set_count`` again.

The trace is "measured" on the simulated axis itself: its friction truth (the ball model
times the plant's 40 ball sets) along the identification profile, with 1 % force noise
and 0.1 um encoder steps. Diagnosed and deployed in ``simulate``, its table must give the
error the diagnosis predicts: the error of a feedforward that is the truth itself, plus
the held-out force error carried through the loop (the loop is linear in a small force
error, so a relative force error r moves the error by about r times the error with no
feedforward, where the whole friction acts). Before the fix it gave 1000x more.
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gms_comp.app.cli import main
from gms_comp.config import default_config_path
from gms_comp.physics.config import load_ball_config
from gms_comp.physics.transient import BallSetFriction
from gms_comp.runtime.observer import FrictionObserver
from gms_comp.tables.table import read_table, table_to_dict
from sim import tracegen
from sim.kernels import truth_force
from sim.link import DirectLink
from sim.plant import ScaledFriction, compiled_truth
from sim.scenarios import Loop, Physics, load_scenario, score


def _cli(args: list[str]) -> tuple[int, dict[str, Any]]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(args)
    return code, json.loads(out.getvalue()) if code == 0 else {}


def _axis_truth() -> ScaledFriction:
    return ScaledFriction(BallSetFriction(load_ball_config()), load_scenario().plant.ball_set_count)


@pytest.fixture(scope="module")
def deployed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    """A trace of the simulated axis's own friction, its diagnosis and table, and a
    config that deploys that table."""
    tmp = tmp_path_factory.mktemp("deploy")
    truth = compiled_truth(_axis_truth())
    t, x, v = tracegen.identification_profile(1000.0, 0.5)
    force = np.array([truth_force(truth, float(p), float(s)) for p, s in zip(x, v, strict=True)])
    level = float(np.max(np.abs(force)))
    force, x = tracegen.measure(force, x, level, np.random.default_rng(7))
    np.savetxt(
        tmp / "trace.csv", np.column_stack([t, x, force]), delimiter=",",
        header="time_s,position_m,force_N", comments="", fmt="%.12g",
    )  # fmt: skip
    code, diagnosis = _cli(
        ["diagnose", str(tmp / "trace.csv"), "--table", str(tmp / "d.json"), "--json"]
    )
    assert code == 0
    config = tmp / "deploy.toml"
    shutil.copy(default_config_path(), config)
    with config.open("a") as fh:
        fh.write('\n[compensator]\ntable_path = "d.json"\n')
    return config, diagnosis


def test_a_diagnosed_table_deployed_gives_the_error_the_diagnosis_predicts(
    deployed: tuple[Path, dict[str, Any]],
) -> None:
    config, diagnosis = deployed
    table = read_table(config.parent / "d.json")
    assert table.scaled_by is None  # measured on the whole axis: nothing to scale
    code, report = _cli(["simulate", str(config), "--json"])
    assert code == 0
    peaks = {k: v["peak_reversal_error_m"] for k, v in report["strategies"].items()}
    s = load_scenario(config)
    truth_ff = FrictionObserver(
        _axis_truth(), s.plant.force_constant_N_per_A, s.controller.servo_period_s, 1.0,
        s.compensator,
    )  # fmt: skip
    run = Loop.build(s, Physics()).run(truth_ff, DirectLink(s.scenario.transport_delay_cycles))
    truth_peak = score(run, s.scenario)["peak_reversal_error_m"]
    assert truth_peak is not None
    relative_force_error = diagnosis["extended_rms_N"] / diagnosis["baseline"]["sliding_force_N"]
    # a peak of a force error whose held-out RMS is known: 4 RMS (a Gaussian's peak over
    # the run's 10^4 cycles); 20 trace seeds: 8.7 to 23.5 nm against 27.6 to 29.6 nm
    predicted = truth_peak + 4 * relative_force_error * peaks["none"]
    assert peaks["gms"] <= predicted
    assert peaks["gms"] < peaks["none"] / 10


def test_a_table_that_needs_more_than_the_current_limit_is_refused_at_start(
    deployed: tuple[Path, dict[str, Any]], capsys: pytest.CaptureFixture[str]
) -> None:
    """The old meaning (the diagnosed table times 40 ball sets) asks for about 7 A of a
    3 A feedforward limit: one line with the figures, exit 2, nothing simulated."""
    config, _ = deployed
    doc = table_to_dict(read_table(config.parent / "d.json"))
    doc["limit_N"] = [40 * w for w in doc["limit_N"]]
    (config.parent / "d.json").write_text(json.dumps(doc))
    try:
        assert main(["simulate", str(config)]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and "simulating" not in err
        assert "needs" in err and "compensator.current_limit_A = 3 A" in err
    finally:
        doc["limit_N"] = [w / 40 for w in doc["limit_N"]]
        (config.parent / "d.json").write_text(json.dumps(doc))
