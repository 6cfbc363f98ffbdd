"""The residual-structure test behind ``unknown``: a local friction spot is found where it
acts, white noise and smooth misfits are not (hand-made residuals, known answers)."""

from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np
from scipy import signal

from gms_comp.measured.diagnosis import structure as st
from gms_comp.measured.diagnosis.config import SplitConfig, StructureConfig
from gms_comp.measured.diagnosis.prepare import noise_at_rest
from gms_comp.runtime import effects as fx

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
    spot = st._spot(r, x, d, NOISE, StructureConfig())
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
    assert st._spot(r, x, d, NOISE, StructureConfig()) is None
    once = same & (d > 0)  # or one way only
    r2 = rng.normal(0, NOISE, x.size)
    r2[once] += 0.8
    assert st._spot(r2, x, d, NOISE, StructureConfig()) is None


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
    spot = st._spot_everywhere([_part(x, d)], [r], NOISE, StructureConfig())  # type: ignore[list-item]
    assert spot is not None and spot.rms_N >= StructureConfig().spot_ratio * NOISE
    held_only = st._spot(r[held], x[held], d[held], NOISE, StructureConfig())
    assert held_only is None or held_only.rms_N < StructureConfig().spot_ratio * NOISE


def test_white_noise_and_a_smooth_level_error_are_no_spot_above_the_threshold() -> None:
    rng = np.random.default_rng(2)
    x, d = _stroke()
    r = rng.normal(0, NOISE, x.size)
    assert (
        st._spot(r, x, d, NOISE, StructureConfig()) is None
    )  # no bin mean 8 standard errors from zero
    smooth = r + 0.02 * d  # a level error of a fifth of the noise everywhere
    spot = st._spot(smooth, x, d, NOISE, StructureConfig())
    size = 0.0 if spot is None else spot.rms_N
    assert size < StructureConfig().spot_ratio * NOISE  # far below a spot's threshold


def _one_way(n: int = 40_000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Out over 10 mm at a steady speed and back over the last 5 mm only: positions,
    directions and the steady samples (the speed's ramps at the ends excluded)."""
    s = np.linspace(0.0, 1.0, n)
    x = np.where(s < 2 / 3, 15e-3 * s, 10e-3 - 15e-3 * (s - 2 / 3))
    d = np.sign(np.gradient(x))
    steady = np.ones(n, dtype=bool)
    steady[:50] = steady[-50:] = steady[n * 2 // 3 - 50 : n * 2 // 3 + 50] = False
    return x, d, steady


def test_a_bump_crossed_one_way_only_is_a_spot_where_the_other_way_is_never_travelled() -> None:
    rng = np.random.default_rng(5)
    x, d, steady = _one_way()
    r = rng.normal(0, NOISE, x.size)
    bump = np.abs(x - 2.3e-3) < 0.15e-3  # 0.3 mm, short of where the way back ends
    r[bump] += 0.8 * d[bump]
    assert (
        st._spot(r, x, d, NOISE, StructureConfig()) is None
    )  # no bin the other way to check it against
    spot = st._spot(r, x, d, NOISE, StructureConfig(), steady)
    assert spot is not None and 0.7 <= spot.rms_N <= 0.9
    assert "not crossed the other way" in spot.where
    centre = float(re.search(r"near x = ([-\d.]+) mm", spot.where).group(1))  # type: ignore[union-attr]
    assert 2.1 < centre < 2.5


def test_one_way_only_a_feature_wider_than_a_bin_at_a_steady_speed_is_a_spot() -> None:
    rng = np.random.default_rng(6)
    x, d, steady = _one_way()
    r = rng.normal(0, NOISE, x.size)
    narrow = (x >= 2.26e-3) & (x < 2.36e-3)  # within one 0.125 mm bin
    r[narrow] += 0.8 * d[narrow]
    assert st._spot(r, x, d, NOISE, StructureConfig(), steady) is None
    r = rng.normal(0, NOISE, x.size)
    ramp = np.abs(x - 2.3e-3) < 0.15e-3  # a misfit where the motion is not steady
    r[ramp] += 0.8
    assert st._spot(r, x, d, NOISE, StructureConfig(), steady & ~ramp) is None
    r = rng.normal(0, NOISE, x.size)
    back = np.abs(x - 7.3e-3) < 0.15e-3  # travelled both ways, one of them clean
    r[back & (d > 0)] += 0.8
    assert st._spot(r, x, d, NOISE, StructureConfig(), steady) is None


def test_a_residual_far_above_the_noise_is_structure_though_no_one_quantity_holds_it() -> None:
    # a level error that changes sign with the position and with the direction (its mean
    # over either alone is zero), 4 x the noise: the bins of one quantity read nothing
    rng = np.random.default_rng(4)
    x, d = _stroke()
    noise = rng.normal(0, NOISE, x.size)
    joint = 0.4 * np.sign(x - 5e-3) * d
    r = noise + joint
    level = 5.0
    found = st._unexplained(r, NOISE, 0.03 * level, level, StructureConfig())
    assert found is not None and found.by == "residual"
    assert abs(found.rms_N - 0.4) < 0.02  # what stands above the noise
    assert re.search(
        r"stands 4(\.\d)? x the noise \(8(\.\d)? % of the sliding force\)", found.where
    )
    # white noise alone, and the same residual on a level it is under 3 % of, are not
    assert st._unexplained(noise, NOISE, 0.03 * level, level, StructureConfig()) is None
    assert st._unexplained(r, NOISE, 0.03 * 20.0, 20.0, StructureConfig()) is None
    # 2.5 x the noise is not far enough above it
    mild = noise + 0.229 * np.sign(x - 5e-3) * d
    assert st._unexplained(mild, NOISE, 0.03, 1.0, StructureConfig()) is None


def test_a_description_names_the_findings_that_are_structure_on_their_own() -> None:
    # a spot far larger than the rest, then a tone and a position dependence that each
    # pass the thresholds (floor 0.3 N), a drift that does too but comes fourth, a phase
    # misfit that does not
    found = [
        st.Finding("spot", 2.0, "a spot"),
        st.Finding("frequency", 0.5, "a tone"),
        st.Finding("position", 0.4, "by position"),
        st.Finding("time", 0.35, "over time"),
        st.Finding("phase", 0.05, "by phase"),
    ]
    described = st.Structure(NOISE, tuple(found), True, 0.3).description()
    assert described == "a spot; a tone; by position"
    # without a floor, only what is half the largest's size
    assert st.Structure(NOISE, tuple(found), True).description() == "a spot"
    assert st.Structure(NOISE, tuple(found), False, 0.3).description() == ""


def _step_and_stop(fs: float = 2000.0) -> SimpleNamespace:
    """Moves of 5 mm at 10 mm/s, back and forth, each followed by a 0.4 s standstill (the
    fields of a fitted part the standstill reading takes: path and measured position)."""
    move, rest = np.full(int(0.5 * fs), 10e-3), np.zeros(int(0.4 * fs))
    v = np.concatenate([np.concatenate([s * move, rest]) for s in (1.0, -1.0) * 10])
    t = np.arange(v.size) / fs
    x = np.cumsum(v) / fs
    a = np.gradient(v, t)
    ctx = fx.Context.along(t, x, v, a, np.zeros(v.size))
    return SimpleNamespace(ctx=ctx, part=SimpleNamespace(path_position_m=x))


def test_coloured_noise_read_at_rest_is_noise_not_an_unexplained_residual() -> None:
    # a sensor's noise low-passed far below the sampling rate: its sample-to-sample
    # differences see a fraction of it, so the residual would stand many times "the
    # noise"; the one noise the diagnosis reads (prepare.noise_at_rest) sees all of it at
    # rest, where the force is constant, and the residual is noise
    part = _step_and_stop()
    n = part.ctx.time_s.size
    rng = np.random.default_rng(5)
    sos = signal.butter(2, 60.0, fs=2000.0, output="sos")
    coloured = signal.sosfiltfilt(sos, rng.normal(size=n))
    coloured *= 0.4 / np.std(coloured)
    level = 10.0  # the noise is 4 % of it
    rules = StructureConfig()
    differences = float(np.std(np.diff(coloured)) / np.sqrt(2.0))
    assert differences < 0.2 * 0.4
    assert st._unexplained(coloured, differences, 0.03 * level, level, rules) is not None
    read = noise_at_rest(coloured, part.ctx.position_m, SplitConfig())
    assert abs(read - 0.4) < 0.06
    assert st._unexplained(coloured, read, 0.03 * level, level, rules) is None
    # a misfit in motion (a level 0.5 N off, of opposite sign each way) on white noise is
    # structure against that same reading
    white = rng.normal(0, NOISE, n)
    misfit = white + 0.5 * np.sign(part.ctx.velocity_m_s)
    read = noise_at_rest(white, part.ctx.position_m, SplitConfig())
    assert abs(read / NOISE - 1.0) < 0.05
    assert st._unexplained(misfit, read, 0.3, level, rules) is not None
