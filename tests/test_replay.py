"""The replay of a measured closed-loop run (issue 14) against the EMPS benchmark's numbers.

The reference rows are the benchmark paper's (Janot, Gautier, Brunot 2019, §3.5,
relative errors of Simulation_EMPS.m with the IDIM-LS parameters) and the position error
RMS of ../shared/data/emps/simulate_closed_loop.py; the replay must give them to three
significant digits.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gms_comp import replay
from sim.position_loop import PositionLoop, RigidAxisModel, simulate_loop


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
