"""The shape-size agreement (selection.agreed) on a fit with a known fixed point."""

from __future__ import annotations

import math

import numpy as np

from gms_comp.measured.diagnosis.candidates import Option
from gms_comp.measured.diagnosis.selection import CONSISTENCY_STEPS, agreed
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
