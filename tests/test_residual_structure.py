"""The residual-structure test behind ``unknown``: a local friction spot is found where it
acts, white noise and smooth misfits are not (hand-made residuals, known answers)."""

from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np

from gms_comp.measured.diagnosis import structure as st

NOISE = 0.1


def _stroke(n: int = 40_000) -> tuple[np.ndarray, np.ndarray]:
    """Back-and-forth over 10 mm: positions and directions."""
    x = 5e-3 * (1 - np.cos(np.linspace(0, 8 * np.pi, n)))
    d = np.sign(np.gradient(x))
    return x, d


def test_a_bump_on_a_few_samples_is_a_spot_with_its_place_and_size() -> None:
    rng = np.random.default_rng(1)
    x, d = _stroke()
    r = rng.normal(0, NOISE, x.size)
    bump = np.abs(x - 3.1e-3) < 0.1e-3  # 0.2 mm; friction: against the motion both ways
    r[bump] += 0.8 * d[bump]
    assert np.count_nonzero(bump) < 0.02 * x.size  # a small share of the samples
    spot = st._spot(r, x, d, NOISE)
    assert spot is not None
    # a bin within the bump (bins are 0.125 mm, the bump 0.2 mm): its samples carry 0.8 N
    assert 0.7 <= spot.rms_N <= 0.9
    centre = float(re.search(r"near x = ([-\d.]+) mm", spot.where).group(1))  # type: ignore[union-attr]
    assert 3.0 < centre < 3.2
    assert "-0.8" in spot.where or "-0.7" in spot.where  # the other way, opposite sign


def test_a_local_misfit_of_one_sign_both_ways_is_not_a_friction_spot() -> None:
    # a force at one place that does not turn with the motion (an inertia misfit where
    # every start accelerates the same way) is not friction there
    rng = np.random.default_rng(4)
    x, d = _stroke()
    r = rng.normal(0, NOISE, x.size)
    same = np.abs(x - 3.1e-3) < 0.1e-3
    r[same] += 0.8
    assert st._spot(r, x, d, NOISE) is None
    once = same & (d > 0)  # or one way only
    r2 = rng.normal(0, NOISE, x.size)
    r2[once] += 0.8
    assert st._spot(r2, x, d, NOISE) is None


def _part(x: np.ndarray, d: np.ndarray) -> SimpleNamespace:
    """The fields of a fitted part the spot scan reads (its path)."""
    ctx = SimpleNamespace(
        velocity_m_s=1e-3 * d, position_m=x, direction=d, acceleration_m_s2=np.gradient(d)
    )
    return SimpleNamespace(ctx=ctx)


def test_a_bump_outside_the_held_out_blocks_is_still_a_spot() -> None:
    rng = np.random.default_rng(3)
    x, d = _stroke()
    r = rng.normal(0, NOISE, x.size)
    held = np.zeros(x.size, dtype=bool)
    held[: x.size // 5] = True  # the first fifth held out: one of four passes, forward
    bump = (np.abs(x - 6.1e-3) < 0.1e-3) & ~held  # crossed only where fitted
    r[bump] += 0.8 * d[bump]
    spot = st._spot_everywhere([_part(x, d)], [r])  # type: ignore[list-item]
    assert spot is not None and spot.rms_N >= st.SPOT_RATIO * NOISE
    held_only = st._spot(r[held], x[held], d[held], NOISE)
    assert held_only is None or held_only.rms_N < st.SPOT_RATIO * NOISE


def test_white_noise_and_a_smooth_level_error_are_no_spot_above_the_threshold() -> None:
    rng = np.random.default_rng(2)
    x, d = _stroke()
    r = rng.normal(0, NOISE, x.size)
    assert st._spot(r, x, d, NOISE) is None  # no bin mean 8 standard errors from zero
    smooth = r + 0.02 * d  # a level error of a fifth of the noise everywhere
    spot = st._spot(smooth, x, d, NOISE)
    size = 0.0 if spot is None else spot.rms_N
    assert size < st.SPOT_RATIO * NOISE  # far below a spot's threshold
