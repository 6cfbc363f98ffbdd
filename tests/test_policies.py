"""The diagnosis policies (gms_comp.measured.policies): one per catalogue effect, their
grids, where an effect acts, what it is told apart from, and how its size is read."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gms_comp.gms import GmsParams
from gms_comp.measured.diagnosis.candidates import (
    Option,
    Trial,
    best_held_out,
    where_acting,
)
from gms_comp.measured.diagnosis.config import SelectionConfig
from gms_comp.measured.diagnosis.selection import local_search
from gms_comp.measured.policies import POLICIES, Leftover, leftover, policy
from gms_comp.measured.policies.direction_asymmetry import DirectionAsymmetryPolicy
from gms_comp.measured.policies.dwell_time import DwellTimePolicy
from gms_comp.measured.policies.offset import OffsetPolicy
from gms_comp.measured.policies.position_ripple import PositionRipplePolicy
from gms_comp.measured.policies.stribeck import StribeckPolicy
from gms_comp.measured.policies.viscous import ViscousPolicy
from gms_comp.runtime import effects as fx

ELEMENTS = GmsParams(np.array([2e5, 1e6]), np.array([1.0, 4.0]), slip_level=1.2)


def _ctx(t: np.ndarray, x: np.ndarray, still: float = 1e-4) -> fx.Context:
    v = np.gradient(x, t)
    a = np.gradient(v, t)
    return fx.Context.along(t, x, v, a, np.ones_like(t), still)


def _triangle(n: int, amp: float, dt: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(n) * dt
    x = amp * (2 / np.pi) * np.arcsin(np.sin(2 * np.pi * t / (n * dt / 2)))
    return t, x


def _slide_hold_slide() -> tuple[np.ndarray, ...]:
    """0.1 ms samples: 30 um forward at 0.3 mm/s, 0.5 s at rest, then 30 um on."""
    v_move = np.full(1000, 3e-4)
    v = np.concatenate([v_move, np.zeros(5000), v_move, np.zeros(500)])
    x = np.cumsum(v) * 1e-4
    return np.arange(x.size) * 1e-4, x, v


def test_every_catalogue_effect_has_one_policy() -> None:
    assert list(POLICIES) == list(fx.CATALOGUE)
    for name, rules in POLICIES.items():
        assert rules.effect is fx.CATALOGUE[name]
        assert rules.size_parameter and rules.to_see_smaller


@pytest.mark.parametrize("periods", [1.6, 2.8, 6.0])
def test_ripple_grid_finds_a_ripple_of_few_periods_over_the_stroke(periods: float) -> None:
    """Over a 12 mm stroke (back and forth), a ripple of ``periods`` periods is among the
    wavelengths the grid tries (within its fine step): 1.6 and 2.8 periods, independent
    traces' ripples, lay beyond the third of the stroke the grid ended at before."""
    t, x = _triangle(20000, 6e-3)
    wavelength = 12e-3 / periods
    residual = 0.8 * np.sin(2 * np.pi * x / wavelength + 0.4)
    ctx = _ctx(t, x)
    left = Leftover.of(residual, ctx.moving > 0)
    tried = [s["wavelength_m"] for s in PositionRipplePolicy.shape_grid(ctx, left, 1e-6)]
    nearest = min(tried, key=lambda w: abs(np.log(w / wavelength)))
    assert nearest == pytest.approx(wavelength, rel=0.01)
    low, high = PositionRipplePolicy.shape_bounds(ctx, 1e-6)["wavelength_m"]
    assert low < wavelength <= high


@pytest.mark.parametrize("periods", [12.0, 40.0])
def test_ripple_wavelength_is_searched_finer_than_its_grid(periods: float) -> None:
    """A ripple of ``periods`` periods over a 40 mm stroke, its wavelength halfway between
    two of the grid's fine values: from the grid's best, the search with the ripple's
    own steps lands within 1e-4 (the phase then moves by under 2 pi x 40 x 1e-4 = 0.03
    rad over the stroke); the other shapes' 8-30 % steps leave it where the grid put it
    (position_ripple-124 of the independent generator: 0.17 % off, 0.26 rad over its 30
    periods, the held-out RMS 30 % above the noise)."""
    t, x = _triangle(80000, 20e-3, 5e-4)
    ctx = _ctx(t, x)
    left = Leftover.of(np.sin(2 * np.pi * x / (40e-3 / periods)), ctx.moving > 0)
    grid = PositionRipplePolicy.shape_grid(ctx, left, 1e-6)
    # the fine grids of neighbouring scan points share values up to rounding: one of each
    fine = list(np.exp(np.unique(np.round(np.log([s["wavelength_m"] for s in grid]), 9))))
    at = int(np.argmin([abs(np.log(w * periods / 40e-3)) for w in fine]))
    wavelength = math.sqrt(fine[at] * fine[at + 1])
    noise = np.random.default_rng(3).normal(0.0, 0.2, x.size)
    residual = 0.8 * np.sin(2 * np.pi * x / wavelength - 1.1) + noise

    def cost(opt: Option) -> float:
        basis = fx.PositionRipple.basis(ctx, opt.shape)
        fitted = np.linalg.lstsq(basis, residual, rcond=None)[0]
        return float(np.sqrt(np.mean((residual - basis @ fitted) ** 2)))

    start = min((Option(fx.PositionRipple, s) for s in grid), key=cost)
    assert abs(start.shape["wavelength_m"] / wavelength - 1) > 5e-4
    bounds = PositionRipplePolicy.shape_bounds(ctx, 1e-6)
    steps = PositionRipplePolicy.shape_steps(ctx)
    found, _ = local_search(start, cost, cost(start), bounds, (), steps)
    assert found.shape["wavelength_m"] == pytest.approx(wavelength, rel=1e-4)
    coarse, _ = local_search(start, cost, cost(start), bounds)
    assert coarse.shape == start.shape


@given(
    st.integers(0, 6),
    st.integers(0, 2**32 - 1),
    st.booleans(),
)
@settings(max_examples=40, deadline=None)
def test_a_pair_s_gain_is_what_least_squares_on_the_design_and_the_pair_lowers(
    width: int, seed: int, degenerate: bool
) -> None:
    """On every row (fewer than the scan samples), the gain of each pair of columns is
    the drop of the squared residual from a least-squares fit on the design to one on
    the design and the pair (numpy's lstsq); a zero or repeated design column changes
    nothing."""
    rng = np.random.default_rng(seed)
    n = 300
    design = rng.normal(size=(n, width)) * np.geomspace(1e-3, 1e3, width)
    if degenerate and width >= 2:
        design[:, 0] = 0.0
        design[:, 1] = design[:, -1] * 3.0
    residual = rng.normal(size=n) + design @ rng.normal(size=width)
    first, second = rng.normal(size=(n, 5)), rng.normal(size=(n, 5))
    left = Leftover.of(residual, np.ones(n, dtype=bool), design)

    def sse(columns: np.ndarray) -> float:
        fitted = np.linalg.lstsq(columns, residual, rcond=None)[0]
        return float(np.sum((residual - columns @ fitted) ** 2))

    expected = [
        sse(design) - sse(np.column_stack([design, first[:, i], second[:, i]])) for i in range(5)
    ]
    assert np.allclose(left.pair_gains(first, second), expected, rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("count", [10, 8000, 8001, 100_000])
def test_the_scan_reads_blocks_of_consecutive_rows_of_those_it_may_read(count: int) -> None:
    """Of ``count`` rows it may read (every other row of a longer path), the scan reads
    all up to ``SCAN_ROWS``; above that about ``SCAN_ROWS`` of them, in runs of
    ``BLOCK_ROWS`` consecutive ones of those rows, evenly spread."""
    read = np.zeros(2 * count, dtype=bool)
    read[1::2] = True
    rows = leftover.sample_rows(read)
    assert np.all(read[rows]) and np.all(np.diff(rows) > 0)
    if count <= leftover.SCAN_ROWS:
        assert rows.size == count
        return
    assert leftover.SCAN_ROWS / 2 <= rows.size <= leftover.SCAN_ROWS
    at = np.searchsorted(np.flatnonzero(read), rows)
    starts = at[np.flatnonzero(np.diff(at, prepend=-2) != 1)]
    assert np.all(starts % leftover.BLOCK_ROWS == 0)
    assert np.ptp(np.diff(starts)) == 0


def test_a_stribeck_fall_acts_where_it_stops_scaling_the_gms_force() -> None:
    """Slow moves (1 mm/s) with one fast move (20 mm/s, 2 % of the rows) over a Stribeck
    speed of 8 mm/s: the bump's column is the GMS force nearly everywhere (most rows
    by energy); its departure, basis and departure adding up to the GMS force, acts on
    the fast move alone, few rows by the support rule the diagnosis reads."""
    n = 5000
    t = np.arange(n) * 1e-3
    v = np.full(n, 1e-3)
    v[2000:2100] = 20e-3
    x = np.cumsum(v) * 1e-3
    f = np.full(n, 4.0)
    ctx = fx.Context.along(t, x, v, 0 * t, f)
    shape = {"v_s_m_per_s": 8e-3}
    basis = fx.Stribeck.basis(ctx, shape)[:, 0]
    departure = StribeckPolicy.departure(ctx, shape)
    np.testing.assert_allclose(basis + departure, f, rtol=1e-12)
    assert ViscousPolicy.departure(ctx, {}) is None
    fast = np.zeros(n, dtype=bool)
    fast[2000:2100] = True
    acting = where_acting(
        departure[:, None], SelectionConfig()
    )  # the rows holding 90 % of its energy
    assert not np.any(acting & ~fast) and np.count_nonzero(acting) >= 0.85 * fast.sum()
    # the bump read as the rows it acts on: most of them, not an effect at few rows
    assert (
        np.count_nonzero(where_acting(basis[:, None], SelectionConfig()))
        > 0.8 * n
        > SelectionConfig().local_share * n
    )


def test_a_direction_asymmetry_is_told_apart_at_speeds_reached_both_ways() -> None:
    """Forward up to 10 mm/s, back up to 2 mm/s: only moving rows at 2 mm/s or less
    (either way) can tell half the speed from a level of the speed; with a second part
    that moves back at 10 mm/s, every moving row of both; a trace that never moves back
    has none; the other effects do not restrict the rows."""
    t = np.linspace(0.0, 1.0, 1001)
    v = np.where(t < 0.5, 10e-3 * np.sin(2 * np.pi * t), 2e-3 * np.sin(2 * np.pi * t))
    ctx = fx.Context.along(t, 0 * t, v, 0 * t, 0 * t)
    moving = ctx.moving != 0.0
    assert 0 < np.count_nonzero(~moving) < 100
    (apart,) = DirectionAsymmetryPolicy.told_apart([ctx])
    np.testing.assert_array_equal(apart, moving & (np.abs(v) <= np.max(-v[moving])))
    assert 0 < np.sum(apart & (v > 0)) < np.sum(moving & (v > 0))
    assert np.all(apart[moving & (v < 0)])
    back = fx.Context.along(t, 0 * t, -v[::-1], 0 * t, 0 * t)  # back at 10, forward at 2
    both = DirectionAsymmetryPolicy.told_apart([ctx, back])
    for c, m in zip((ctx, back), both, strict=True):
        np.testing.assert_array_equal(m, c.moving != 0.0)
    forward = fx.Context.along(t, 0 * t, np.clip(v, 0.0, None), 0 * t, 0 * t)
    assert not np.any(DirectionAsymmetryPolicy.told_apart([forward])[0])
    assert StribeckPolicy.told_apart([ctx]) is None and OffsetPolicy.told_apart([ctx]) is None


def test_a_dwell_gain_along_a_trace_is_its_gain_after_the_median_standstill() -> None:
    t, x, v = _slide_hold_slide()
    ctx = fx.Context.along(t, x, v, 0 * t, 0 * t)
    effect = fx.DwellTime(0.2, 0.1, 0.2)
    figures = DwellTimePolicy.in_context(effect, ctx)
    assert figures["median_dwell_s"] == pytest.approx(0.5, abs=1e-9)
    assert figures["gain_after_median_dwell"] == pytest.approx(0.2 * math.log(6.0), rel=1e-12)
    moving = fx.Context.along(t[:1000], x[:1000], v[:1000], 0 * t[:1000], 0 * t[:1000])
    assert DwellTimePolicy.in_context(effect, moving) == {}  # no standstill ended: nothing to say
    assert OffsetPolicy.in_context(fx.Offset(1.0), ctx) == {}
    # what the diagnosis sizes it by against its least effect (and 0 without a standstill)
    assert DwellTimePolicy.relative_size(effect, ctx) == figures["gain_after_median_dwell"]
    assert DwellTimePolicy.relative_size(effect, moving) == 0.0
    assert OffsetPolicy.relative_size(fx.Offset(1.0), ctx) is None


@pytest.mark.parametrize(
    "effect",
    [c for c in fx.CATALOGUE.values() if not issubclass(c, fx.FilterEffect)],
    ids=lambda c: c.name,
)
def test_a_basis_said_to_be_the_motion_s_alone_is_the_same_under_any_gms(
    effect: type[fx.Effect],
) -> None:
    # the diagnosis keeps such a basis for every baseline fitted to the trace: the flag
    # must be right, and an effect that reads the GMS must not say otherwise
    rng = np.random.default_rng(3)
    n = 400
    t = np.arange(n) * 1e-3
    v = np.repeat(rng.normal(0, 2e-3, n // 40), 40) * (rng.random(n // 40).repeat(40) > 0.3)
    x, a = np.cumsum(v) * 1e-3, np.gradient(v, t)
    one = dataclasses.replace(fx.Context.along(t, x, v, a, np.tanh(x / 1e-5)), gms=ELEMENTS)
    other = dataclasses.replace(
        one, gms_force_N=3.0 * np.tanh(x / 2e-5) + 0.5, gms=_other_elements(ELEMENTS)
    )
    rules = policy(effect)
    shape = {k: math.sqrt(lo * hi) for k, (lo, hi) in rules.shape_bounds(one, 1e-6).items()}
    for key in effect.SHAPE:
        shape.setdefault(key, 1.0)
    same = np.array_equal(effect.basis(one, shape), effect.basis(other, shape))
    assert same is not rules.basis_reads_gms


def _other_elements(params: GmsParams) -> GmsParams:
    """Other elements: limits and stiffnesses changed."""
    return dataclasses.replace(
        params, limit_N=params.limit_N * 1.7, stiffness_N_per_m=params.stiffness_N_per_m * 0.6
    )


def test_a_trial_fitted_at_zero_gives_way_to_a_local_one_fitted_above_it() -> None:
    """Of a grid's trials, the best held out is taken, unless it is the design as it was
    (its effect fitted at zero) acting on many rows: then the best of those fitted above
    zero that act on few rows, to be judged at their events; else it stays."""
    n, m = 1000, 2

    def trial(v_s: float, coefficient: float, held_out: float, acting: int) -> Trial:
        support = np.zeros(n, dtype=bool)
        support[:acting] = True
        theta = np.array([1.0, 0.5, coefficient])
        option = Option(fx.Stribeck, {"v_s_m_per_s": v_s})
        return Trial(option, held_out, theta, np.zeros(n), lambda: support)

    at_zero = trial(1e-3, 0.0, 1.00, 500)
    local = trial(7e-3, 0.2, 1.01, 50)
    local_worse = trial(9e-3, 0.1, 1.03, 40)
    spread = trial(3e-3, 0.3, 1.02, 600)
    assert best_held_out(m, [spread, at_zero, local_worse, local], SelectionConfig()) is local
    # none fitted above zero acts locally: the best held out
    assert best_held_out(m, [spread, at_zero], SelectionConfig()) is at_zero
    # the best held out fitted above zero, or acting locally itself: kept
    lower = trial(5e-3, 0.1, 0.99, 600)
    assert best_held_out(m, [lower, at_zero, local], SelectionConfig()) is lower
    local_zero = trial(8e-3, 0.0, 1.00, 30)
    assert best_held_out(m, [local_zero, local], SelectionConfig()) is local_zero
