"""The shape-size agreement (selection.agreed) on a fit with a known fixed point."""

from __future__ import annotations

import math

import numpy as np

from gms_comp.measured.diagnosis.candidates import Option
from gms_comp.measured.diagnosis.criterion import CONSISTENCY_STEPS, agreed
from gms_comp.runtime import effects as fx


def test_half_steps_reach_a_gain_that_falls_as_its_windows_rise() -> None:
    # a dwell's fitted gain falls as the gain its windows are computed at (reach) rises:
    # gamma = 0.2 (reach / 0.2)^-0.8, fixed point reach = 0.2. Half steps in log shrink the
    # distance by (1 - 0.8) / 2 = 0.1 each: from reach 1 (ln 5 = 1.61 away) to 0.161, then
    # 0.016 (a factor 1.016, within the 1.1 that ends the search): two fits after the first
    calls: list[float] = []

    def fit(opt: Option) -> tuple[Option, np.ndarray]:
        calls.append(opt.shape["reach"])
        return opt, np.array([0.2 * (opt.shape["reach"] / 0.2) ** -0.8])

    first = fit(Option(fx.DwellTime, {"tau_s": 0.1, "reach": 1.0}))
    done = agreed(first, lambda f: f[0], lambda f: f[1], fit)
    assert len(calls) == 3
    assert abs(math.log(done[0].shape["reach"] / 0.2)) < 0.02
    assert done[0].shape["tau_s"] == 0.1  # only what the size sets moves


def test_a_fit_that_never_agrees_stops_after_the_bound() -> None:
    # the gain always twice the reach: no fixed point, the search ends after its bound
    calls: list[float] = []

    def fit(opt: Option) -> tuple[Option, np.ndarray]:
        calls.append(opt.shape["reach"])
        return opt, np.array([2.0 * opt.shape["reach"]])

    agreed(fit(Option(fx.DwellTime, {"tau_s": 0.1, "reach": 0.01})), lambda f: f[0],
           lambda f: f[1], fit)  # fmt: skip
    assert len(calls) == 1 + CONSISTENCY_STEPS


def _factor(fitted: tuple[Option, np.ndarray]) -> float:
    """How far a fit's reach is from its fitted gain (1: they agree)."""
    reach, gain = fitted[0].shape["reach"], float(fitted[1][0])
    return max(reach / gain, gain / reach)


def test_a_steep_fall_is_reached_by_bisection() -> None:
    # gamma = 0.2 (reach / 0.2)^-4: a half step in log multiplies the distance to the
    # fixed point by (1 - 4) / 2 = -1.5, so half steps alone swing ever wider. Once the
    # steps have gone both ways they bisect: from reach 0.1 the fixed point 0.2 is found
    # within the 1.1 that ends the search (a factor 1.1 between reach and gain is within
    # 1.1^(1/5) of the fixed point), within the bound
    calls: list[float] = []

    def fit(opt: Option) -> tuple[Option, np.ndarray]:
        calls.append(opt.shape["reach"])
        return opt, np.array([0.2 * (opt.shape["reach"] / 0.2) ** -4.0])

    done = agreed(fit(Option(fx.DwellTime, {"tau_s": 0.1, "reach": 0.1})), lambda f: f[0],
                  lambda f: f[1], fit)  # fmt: skip
    assert _factor(done) <= 1.1
    assert abs(math.log(done[0].shape["reach"] / 0.2)) <= math.log(1.1) / 5 + 1e-12
    assert len(calls) <= 1 + CONSISTENCY_STEPS


def test_a_gain_that_jumps_across_agreement_returns_the_closest_fit() -> None:
    # the fitted gain jumps from 0.3 to 0.05 at reach 0.15 (a raised element that holds
    # at one gain and slips at the next): no reach agrees; the fit returned is the one
    # that agrees best of those made, the search bisecting towards the jump
    made: list[tuple[Option, np.ndarray]] = []

    def fit(opt: Option) -> tuple[Option, np.ndarray]:
        made.append((opt, np.array([0.3 if opt.shape["reach"] < 0.15 else 0.05])))
        return made[-1]

    done = agreed(fit(Option(fx.DwellTime, {"tau_s": 0.1, "reach": 0.03})), lambda f: f[0],
                  lambda f: f[1], fit)  # fmt: skip
    assert len(made) == 1 + CONSISTENCY_STEPS
    assert _factor(done) == min(_factor(f) for f in made)
    # bisection brackets the jump: the last reaches tried lie close on either side of it
    last = sorted(f[0].shape["reach"] for f in made[-3:])
    assert last[0] < 0.15 <= last[-1] and last[-1] / last[0] < 1.5
