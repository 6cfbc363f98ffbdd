"""The level adaptation: frozen where friction cannot be seen, bounded, and dissipative.

docs/adaptation.md: with the gates open a step is lambda+ = P(lambda + g (rho - lambda)),
P the clamp to the bounds, so for the error e = lambda - lambda* and the measurement's
n = rho - lambda* (lambda* within the bounds), |e+| <= (1 - g)|e| + g|n|; with the gates
shut lambda+ = lambda. The numeric check runs the compiled update itself over 10^7
random steps (changing true levels, noise, outliers, standstill, acceleration, reversals).
"""

from __future__ import annotations

import numba
import numpy as np
import pytest

from gms_comp.gms import GmsParams, GmsStream
from gms_comp.runtime.observer import CompensatorConfig, FrictionObserver, adapt_level

KF = 60.0
GAIN = 0.05  # per step: far above a real one (1/s at 4 kHz: 2.5e-4), to stress the bound


def _observer(**cfg: float) -> FrictionObserver:
    config = CompensatorConfig(adaptation_rate_per_s=GAIN * 4000.0, **cfg)  # type: ignore[arg-type]
    model = GmsStream(GmsParams(np.array([1e6]), np.array([10.0])))
    return FrictionObserver(model, KF, 2.5e-4, 1.0, config)


def _sliding(obs: FrictionObserver, velocity: float = 0.01) -> float:
    """Step the model into forward sliding; the model's friction current."""
    for x in np.linspace(0.0, 1e-4, 20):
        obs.step(float(x), velocity)
    return obs.model_force_N / KF


@pytest.mark.parametrize(
    ("what", "drive", "inertial", "velocity"),
    [
        ("standstill", 1.5, 0.0, 0.0),
        ("too slow", 1.5, 0.0, 1e-3),
        ("accelerating", 1.5 + 2.0, 2.0, 0.01),  # the mass takes 2x the friction current
        ("moving against the model (after a reversal)", -1.5, 0.0, -0.01),
        ("an outlier (a collision, a jam)", 5.0, 0.0, 0.01),
    ],
)
def test_the_level_freezes_where_it_cannot_see_friction(
    what: str, drive: float, inertial: float, velocity: float
) -> None:
    obs = _observer()
    friction_A = _sliding(obs)
    for _ in range(1000):
        obs.adapt(drive * friction_A, inertial * friction_A, velocity)
    assert obs.level == 1.0, what


def test_the_level_follows_the_drive_and_stays_within_its_bounds() -> None:
    obs = _observer()
    friction_A = _sliding(obs)
    for _ in range(1000):  # 1.5 x the model: within the outlier gate, and a true level
        obs.adapt(1.5 * friction_A, 0.0, 0.01)
    assert obs.level == pytest.approx(1.5, rel=1e-9)
    for _ in range(5000):  # always 1.9 x the level: it climbs to its bound, no further
        obs.adapt(1.9 * obs.level * friction_A, 0.0, 0.01)
    assert obs.level == 2.0


@numba.njit(cache=True)
def _random_walk(
    state: np.ndarray, params: np.ndarray, steps: int, seed: int, lo: float, hi: float
) -> tuple[int, int, float, int]:  # pragma: no cover
    """``steps`` updates with random inputs; counts of bound and dissipation violations,
    the largest excess of |e+| over (1 - g)|e| + g|n|, and how many steps adapted."""
    np.random.seed(seed)
    gain, kf = params[3], params[0]
    truth = 1.0
    out_of_bounds = 0
    violations = 0
    worst = 0.0
    adapted = 0
    for _ in range(steps):
        if np.random.random() < 1e-4:  # the true level moves now and then
            truth = lo + (hi - lo) * np.random.random()
        force = 10.0 * (np.random.random() - 0.3)  # both signs, and near 0
        state[3] = force
        velocity = 0.03 * (np.random.random() - 0.3)
        inertial = 0.0 if np.random.random() < 0.8 else 0.5 * np.random.normal() * force / kf
        noise = 0.0 if np.random.random() < 0.5 else 0.05 * np.random.normal()
        if np.random.random() < 0.01:
            noise += 5.0 * np.random.normal()  # outliers
        drive = (truth + noise) * force / kf + inertial
        before = state[1]
        adapt_level(state, params, drive, inertial, velocity)
        after = state[1]
        if not lo <= after <= hi:
            out_of_bounds += 1
        if after != before:
            adapted += 1
            ratio = (drive - inertial) / (force / kf)
            excess = abs(after - truth) - (1.0 - gain) * abs(before - truth)
            excess -= gain * abs(ratio - truth)
            worst = max(worst, excess)
            if excess > 1e-12:
                violations += 1
    return out_of_bounds, violations, worst, adapted


def test_the_update_is_dissipative_over_ten_million_steps() -> None:
    obs = _observer()
    lo, hi = obs.config.adaptation_level_bounds
    out_of_bounds, violations, worst, adapted = _random_walk(
        obs.state, obs.params, 10_000_000, 7, lo, hi
    )
    assert out_of_bounds == 0
    assert violations == 0, worst
    assert adapted > 1_000_000  # the gates let a good share through: the bound was tested
