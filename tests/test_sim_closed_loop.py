"""Trajectories, link and the closed loop, with a GMS stand-in as friction truth."""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Literal

import numpy as np
import pytest

from gms_comp.app.commands.diagnose_closed_loop import _effect_force
from gms_comp.gms import GmsParams, GmsStream, scaled
from gms_comp.runtime import effects as fx
from gms_comp.tables.table import Fidelity, GmsTable
from sim.link import DirectLink
from sim.plant import ZeroFriction
from sim.scenarios import (
    Loop,
    Physics,
    Scenario,
    axis_scenarios,
    build_observer,
    build_reference,
    circularity,
    load_scenario,
    radial_error,
    run_strategies,
    score,
)
from sim.trajectories import circle, reversals, sine, step_stop, stops

SERVO_S = 2.5e-4
# A stand-in truth of one ball set: four elements, presliding over a few micrometres.
STAND_IN = GmsParams(np.array([2e5, 5e4, 1e4, 3e3]), np.array([0.1, 0.08, 0.06, 0.04]))


def _table(params: GmsParams) -> GmsTable:
    """A bare table around ``params``."""
    return GmsTable(params, source_config="test", source_sha256="", fidelity=Fidelity(0.0, 0.0))


def _physics(table: GmsParams = STAND_IN) -> Physics:
    """The stand-in as the truth of one ball set; the table, of the whole axis, is
    ``table`` times the plant's ball sets."""
    return Physics(
        truth=lambda ball: GmsStream(STAND_IN),
        table=lambda s: _table(scaled(table, s.plant.ball_set_count, 1.0)),
    )


def _scenario(**scenario: Any) -> Scenario:
    s = load_scenario()
    short = {"revolutions": 0.6, "dwell_s": 0.05, **scenario}
    return dataclasses.replace(s, scenario=dataclasses.replace(s.scenario, **short))


def test_reference_is_consistent_and_smooth() -> None:
    x, y = circle(0.01, 0.02, 1.0, SERVO_S, 0.01, 0.005, 0.1)
    for ref in (x, y):
        slope = np.gradient(ref.position_m, SERVO_S)[1:-1]
        np.testing.assert_allclose(slope, ref.velocity_m_s[1:-1], rtol=0, atol=1e-3 * 0.02)
        # Two boxcars: |a| <= v / window, exactly the acceleration bound of the filter.
        assert np.max(np.abs(ref.acceleration_m_s2)) <= 0.02 / 0.01 * (1 + 1e-9)
    radius = np.hypot(x.position_m, y.position_m - 0.01)
    quarter = slice(x.cycles // 8, x.cycles // 2)  # away from the ramps
    np.testing.assert_allclose(radius[quarter], 0.01, rtol=2e-3)


def test_reversals_and_stops_are_found() -> None:
    ref = sine(1e-3, 2.0, 2.0, SERVO_S, 0.01, 0.005, 0.1)
    # x = A sin: reverses at a quarter and three quarters of each period (+ filter delay).
    turns = reversals(ref) * SERVO_S
    assert len(turns) == 4
    np.testing.assert_allclose(turns, np.array([0.125, 0.375, 0.625, 0.875]), atol=0.01)
    ((start, end),) = stops(ref, min_stop_s=0.01)
    assert end == ref.cycles
    assert (end - start) * SERVO_S == pytest.approx(0.1, abs=4 * SERVO_S)


def test_direct_link_delays_by_whole_cycles() -> None:
    link = DirectLink(delay_cycles=2)
    assert [link.transfer(k, float(k + 1)) for k in range(5)] == [0.0, 0.0, 1.0, 2.0, 3.0]


def test_friction_truth_opposes_motion_and_dissipates() -> None:
    s = _scenario()
    result = run_strategies(s, ["none"], _physics())["none"]
    v = np.gradient(result.position_m, SERVO_S)
    work_J = np.sum(result.friction_N * v) * SERVO_S
    assert work_J > 0
    sliding = np.abs(result.reference.velocity_m_s) > 0.5 * s.scenario.feed_m_s
    assert np.all(result.friction_N[sliding] * v[sliding] > 0)


def test_compensation_lowers_the_reversal_error() -> None:
    s = _scenario()
    results = run_strategies(s, ["none", "gms"], _physics())
    none, gms = (score(results[k], s.scenario) for k in ("none", "gms"))
    assert none["peak_reversal_error_m"] is not None
    assert gms["peak_reversal_error_m"] is not None
    assert gms["peak_reversal_error_m"] < none["peak_reversal_error_m"] / 3
    assert gms["rms_error_m"] < none["rms_error_m"]  # type: ignore[operator]


def _two_axis_runs(physics: Physics, strategies: list[str]) -> list[dict[str, Any]]:
    """Both axes of a short two-axis circle, each run under ``strategies``."""
    axes = axis_scenarios(_scenario(circle_axis="xy"))
    assert [a.scenario.circle_axis for a in axes] == ["x", "y"]
    return [run_strategies(a, strategies, physics) for a in axes]


def test_frictionless_two_axis_circle_keeps_its_radius() -> None:
    x, y = (axis["none"] for axis in _two_axis_runs(Physics(lambda b: ZeroFriction()), ["none"]))
    assert not np.allclose(x.reference.position_m, y.reference.position_m)
    radial = radial_error(x, y, 0.01)
    # Triangle inequality: the radial error never exceeds the contour's following error.
    assert np.all(np.abs(radial) <= np.hypot(x.error_m, y.error_m) + 1e-15)
    # Two identical linear axes on a circle lag along the path, not across it: without
    # friction the radial error is a small part of the single-axis following error.
    following = max(np.max(np.abs(x.error_m)), np.max(np.abs(y.error_m)))
    assert np.max(np.abs(radial)) < 0.25 * following


def test_gms_lowers_the_quadrant_error_of_the_contour() -> None:
    x, y = _two_axis_runs(_physics(), ["none", "gms"])
    c = _scenario().scenario
    none, gms = (circularity(x[k], y[k], c) for k in ("none", "gms"))
    assert none["peak_quadrant_error_m"] is not None
    assert gms["peak_quadrant_error_m"] is not None
    assert gms["peak_quadrant_error_m"] < none["peak_quadrant_error_m"] / 3
    assert gms["rms_radial_error_m"] < none["rms_radial_error_m"]  # type: ignore[operator]


def test_feedforward_respects_the_compensator_limits() -> None:
    s = _scenario()
    comp = dataclasses.replace(s.compensator, current_limit_A=0.05, rate_limit_A_per_s=50.0)
    results = run_strategies(dataclasses.replace(s, compensator=comp), ["gms"], _physics())
    ff = results["gms"].feedforward_A
    assert np.max(np.abs(ff)) <= 0.05 + 1e-12
    assert np.max(np.abs(np.diff(ff))) <= 50.0 * SERVO_S + 1e-12
    assert math.isclose(np.max(np.abs(ff)), 0.05)  # the limit is reached: it was binding


def test_adaptation_recovers_a_misset_friction_level() -> None:
    s = _scenario(revolutions=1.0)
    comp = dataclasses.replace(s.compensator, friction_level_scale=0.7, adaptation_rate_per_s=5.0)
    s = dataclasses.replace(s, compensator=comp)
    physics = _physics()
    observer = build_observer(s, "gms", physics)
    assert observer is not None
    Loop.build(s, physics).run(observer, DirectLink(1))
    right = 1.0  # the table is the truth here (the whole axis's)
    assert abs(observer.level - right) < 0.5 * abs(observer.initial_level - right)


def test_seed_step_and_stop_profile_keeps_its_steps() -> None:
    ref = step_stop(SERVO_S, 0.002, 0.001, 0.1)
    assert len(stops(ref, min_stop_s=0.01)) == 20  # a stop after each of the 20 steps
    assert len(reversals(ref)) == 1  # up to 1 mm, then back
    assert np.max(ref.position_m) == pytest.approx(1e-3, rel=1e-3)
    assert ref.position_m[-1] == pytest.approx(0.0, abs=1e-9)


class _PythonLink:
    """A direct link the compiled loop does not know: forces the per-cycle path."""

    def __init__(self, delay_cycles: int) -> None:
        self.inner = DirectLink(delay_cycles)

    def transfer(self, cycle: int, current_A: float) -> float:
        return self.inner.transfer(cycle, current_A)


@pytest.mark.parametrize("name", ["none", "coulomb_viscous", "lugre", "gms"])
@pytest.mark.parametrize("feed", ["reference", "measured"])
def test_compiled_run_equals_the_per_cycle_path(
    name: str, feed: Literal["reference", "measured"]
) -> None:
    s = _scenario(revolutions=0.3)
    comp = dataclasses.replace(s.compensator, feed=feed, adaptation_rate_per_s=2.0)
    s = dataclasses.replace(s, compensator=comp)
    physics = _physics()
    loop = Loop.build(s, physics)
    observer = build_observer(s, name, physics)
    compiled = loop.run(observer, DirectLink(2))
    per_cycle = loop.run(observer, _PythonLink(2))
    for field in ("position_m", "feedforward_A", "current_command_A", "friction_N"):
        np.testing.assert_array_equal(getattr(compiled, field), getattr(per_cycle, field))


def test_the_plant_s_reversal_transient_starts_where_the_reference_turns() -> None:
    """In the closed-loop gain, a diagnosed effect acts on the simulated axis from the
    reference's turning point (the contact turns with the motion), not once the retreat
    has passed the deadband, which is when the compensator's stream learns of it."""
    s = load_scenario(None)
    x = build_reference(s).position_m
    band = 2e-6  # coarse, so that the causal latency spans many servo cycles
    transient = fx.ReversalTransient(1.0, 1e-4)
    # a standstill speed far below the vertex's (else its slowest samples count as rest)
    context = {"reversal_deadband_m": band, "standstill_speed_m_s": 1e-9}
    force = _effect_force(s, STAND_IN, [transient], context)
    step = np.sign(np.diff(x))
    moving = np.flatnonzero(step)
    first = moving[0]
    # the last sample at the vertex
    turn = first + int(np.flatnonzero(step[first:] == -step[first])[0])
    retreat = np.abs(x[turn + 1 :] - x[turn])
    passed = turn + 1 + int(np.flatnonzero(retreat > band)[0])  # where a causal path turns
    assert passed - turn > 5
    new = -step[first]
    # the new direction, decaying from about A, at every sample from the turn on
    window = force[turn + 1 : passed + 1]
    assert np.all(np.sign(window) == new)
    assert abs(force[turn + 1]) == pytest.approx(1.0, abs=0.05)
    # and not before (the stroke before the first reversal carries no transient)
    assert np.sign(force[turn]) != new
