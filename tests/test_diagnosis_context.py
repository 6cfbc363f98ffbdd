"""The diagnosis's path context against an independent truth: where a dwell gain acts.

The independent generator (tests/indepgen.py, tests/indepfriction.py) raises the element
limits at the first moving sample after a standstill, per the catalogue's text; its extra
force lives in the first micrometres of each break-away, mostly at speeds far below any
standstill speed a diagnosis could pick from the peak speed. The context the diagnosis
builds from the measured (quantised) positions must mark those samples as not resting and
date the dwell as the truth does, or no dwell column can see them.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from indepfriction import friction
from indepgen import baseline, make_trace

from gms_comp.measured.diagnosis.config import DiagnosisConfig, SplitConfig
from gms_comp.measured.diagnosis.motion import kinematics
from gms_comp.measured.diagnosis.prepare import held_third, prepare, top_blocks, top_rows_held
from gms_comp.measured.traces import Trace
from gms_comp.runtime import effects as fx
from gms_comp.runtime.effects.path import REST_HOLD_S

# The truth is indexed by sample: every sample fitted (not every k-th of a fast trace).
EVERY_SAMPLE = DiagnosisConfig(fit_rate_Hz=0.0)


@functools.cache
def _context(seed: int, cfg: DiagnosisConfig) -> tuple[fx.Context, np.ndarray, np.ndarray]:
    gen = make_trace("dwell_time", seed)
    truth = baseline(seed)[0]
    extra = friction(truth, gen.effects) - friction(truth, ())
    trace = Trace("indep", gen.time_s, gen.position_m, gen.force_N)
    prepared = prepare(trace, "friction", None, cfg)
    ctx = prepared.context(prepared.main, np.zeros(len(trace)))
    # the truth's dwell before each sample: the last standstill (v == 0) that ended
    moving = truth.velocity_m_s != 0.0
    starts = np.flatnonzero(moving[1:] & ~moving[:-1]) + 1
    stops = np.flatnonzero(~moving[1:] & moving[:-1]) + 1
    true_dwell = np.zeros(len(trace))
    for start in starts:
        before = stops[stops < start]
        if before.size:
            true_dwell[start:] = truth.time_s[start] - truth.time_s[before[-1]]
    return ctx, extra, true_dwell


# seed 103: after a rest of 0.97 s the truth creeps 2.5 um forward at up to 7 um/s (below
# any standstill speed) and turns back without stopping; until the turnaround rule
# (path.TURN_FACTOR) the context dated a rest at that slow turnaround and the start's dwell
# from it (25 ms), the truth from the rest before it (16 % of the dwell force's energy
# misdated). Two seeds still fail, for reasons no rest rule can mend:
SLOW_START = pytest.mark.xfail(
    strict=True,
    reason="seed 106: a start so slow (0.01 um/s at the truth's first moving sample) that "
    "the position leaves the 2.4 nm band 15 ms later: the 109 ms dwell is measured 125 ms "
    "(95 % of the energy 14 % off)",
)
COARSE_ENCODER = pytest.mark.xfail(
    strict=True,
    reason="seed 107: a 39 nm encoder; the truth moves 37 ms before the position leaves "
    "the 58 nm band, and its elements stretch in that time (11 % of the energy)",
)


@pytest.mark.parametrize(
    "seed",
    [101, 102, 103, 104, 105, pytest.param(106, marks=SLOW_START),
     pytest.param(107, marks=COARSE_ENCODER), 108, 109, 110],
)  # fmt: skip
def test_the_dwell_force_falls_where_the_context_is_moving_with_the_true_dwell(
    seed: int,
) -> None:
    ctx, extra, true_dwell = _context(seed, EVERY_SAMPLE)
    energy = extra**2
    seen = ctx.resting == 0.0
    assert energy[seen].sum() >= 0.95 * energy.sum()
    # dated as the truth dates it, energy-weighted: within 5 % or 5 ms (a quantised position
    # moves its last step before the truth stops, and leaves the band a few nanometres
    # after the truth starts; 5 % of t_d is at most 5 % of ln(1 + t_d / tau))
    acting = energy > 0
    close = np.abs(ctx.dwell_s - true_dwell) <= np.maximum(0.05 * true_dwell, 5e-3)
    assert energy[acting & close].sum() >= 0.95 * energy.sum()


def test_a_speed_threshold_alone_misses_the_dwell_force() -> None:
    # the rule before the rest band: resting until 1 % of the peak speed is exceeded
    ctx, extra, _ = _context(101, DiagnosisConfig(rest_band_steps=0.0, fit_rate_Hz=0.0))
    energy = extra**2
    assert energy[ctx.resting == 0.0].sum() < 0.3 * energy.sum()


@pytest.mark.parametrize("seed", range(101, 111))
def test_no_rest_is_dated_where_the_truth_does_not_stop(seed: int) -> None:
    # micrometre reversals hold the position within the band for 20-60 ms at each slow
    # turnaround (the truth's velocity only crosses zero): before the turnaround rule the
    # context dated 2-20 such rests on seeds 103, 104, 106, 107 and 110
    gen = make_trace("dwell_time", seed)
    ctx, _, _ = _context(seed, EVERY_SAMPLE)
    moving = baseline(seed)[0].velocity_m_s != 0.0
    true_starts = gen.time_s[np.flatnonzero(moving[1:] & ~moving[:-1]) + 1]
    ours = np.flatnonzero((ctx.resting[1:] == 0.0) & (ctx.resting[:-1] == 1.0)) + 1
    # a rest held for REST_HOLD_S or more (shorter ones: a fast reversal below the
    # standstill speed for a sample or two, whose dwell is too short to raise a limit)
    held = ours[ctx.dwell_s[ours] >= REST_HOLD_S]
    far = [t for t in gen.time_s[held] if np.min(np.abs(true_starts - t)) > 0.1]
    assert far == []


def _truth_starts(seed: int) -> np.ndarray:
    """The samples where the independent truth starts after a standstill of at least
    ``REST_HOLD_S`` (its velocity exactly zero; the record's own first rest is one: its
    dwell is unknown, but the elements stuck through it)."""
    truth = baseline(seed)[0]
    still = np.concatenate([[False], truth.velocity_m_s == 0.0, [False]])
    edges = np.flatnonzero(np.diff(still.astype(int)))
    begin, end = edges[0::2], edges[1::2]
    dt = float(truth.time_s[1] - truth.time_s[0])
    long = (end - begin) * dt >= REST_HOLD_S
    return end[long & (end < truth.time_s.size)]


@pytest.mark.parametrize("seed", range(101, 111))
def test_both_parts_hold_starts_after_a_standstill(seed: int) -> None:
    """A dwell effect acts only where the axis starts after a standstill: the held-out
    rows hold some of the truth's starts, and so do the training rows (on two of these
    traces every third block from the second held none)."""
    gen = make_trace("dwell_time", seed)
    part = prepare(Trace("indep", gen.time_s, gen.position_m, gen.force_N), "friction",
                   None, EVERY_SAMPLE).main  # fmt: skip
    starts = _truth_starts(seed)
    assert starts.size >= 3
    assert np.any(part.held[starts]) and np.any(part.train[starts])


@pytest.mark.parametrize("seed", range(101, 111))
def test_the_training_rows_reach_the_top_speed(seed: int) -> None:
    """The truth's top speeds are in the training rows (a velocity law is otherwise
    extrapolated to the speeds it is judged at): the second third held every row above
    69, 19 and 52 % of the top speed on seeds 104, 105 and 109."""
    gen = make_trace("none", seed)
    part = prepare(Trace("indep", gen.time_s, gen.position_m, gen.force_N), "friction",
                   None, EVERY_SAMPLE).main  # fmt: skip
    speed = np.abs(baseline(seed)[0].velocity_m_s)
    assert float(np.max(speed[part.train])) >= 0.8 * float(np.max(speed))


@pytest.mark.parametrize("seed", range(121, 131))
def test_the_training_rows_reach_the_top_acceleration(seed: int) -> None:
    """The truth's top accelerations are in the training rows (a mass is otherwise fitted
    where the acceleration is small): on seed 124 the second third held both 7.4 m/s^2
    ramps, and the training rows reached 8 % of them."""
    gen = make_trace("none", seed)
    part = prepare(Trace("indep", gen.time_s, gen.position_m, gen.force_N), "friction",
                   None, EVERY_SAMPLE).main  # fmt: skip
    accel = np.abs(baseline(seed)[0].acceleration_m_s2)
    assert float(np.max(accel[part.train])) >= 0.8 * float(np.max(accel))


def test_a_held_block_with_the_only_top_speeds_is_trained_on() -> None:
    """Blocks of 10 rows, the second third held; the top speed only in block 4: that block
    is trained on, the other held blocks stay held; with the top speed also in a training
    block, nothing moves."""
    block = np.repeat(np.arange(9), 10)
    held = block % 3 == 1
    speed = np.full(block.size, 0.01)
    speed[43] = 0.05  # block 4 (held)
    speed[44] = 0.045  # same block, above 0.8 x the top
    moved = top_blocks(block, held, speed, SplitConfig())
    np.testing.assert_array_equal(moved, block == 4)
    speed[51] = 0.041  # block 5 (training) reaches 0.8 x the top
    assert not np.any(top_blocks(block, held, speed, SplitConfig()))


def test_fast_rows_only_in_training_are_split_in_time() -> None:
    """Blocks of 10 rows, the second third held; every row above a fifth of the top speed
    in training block 3 (rows 32-37): the later half of them, from the median row to the
    block's end, is held out; where that half holds every training row at 0.8 x the top
    speed, or the top acceleration, the earlier half from the block's start; fast rows in
    two blocks are split in the block of their median; a single fast row is not split;
    once a held row reaches a fifth, nothing moves."""
    block = np.repeat(np.arange(9), 10)
    held = block % 3 == 1
    speed, accel = np.full(block.size, 0.001), np.zeros(block.size)

    def moved() -> list[int]:
        return np.flatnonzero(top_rows_held(block, held, speed, accel, SplitConfig())).tolist()

    speed[32:38] = [0.01, 0.03, 0.05, 0.05, 0.03, 0.01]
    assert moved() == list(range(35, 40))
    accel[36:38] = 2.0  # the top acceleration in the later half only
    assert moved() == list(range(30, 35))
    accel[:] = 0.0
    speed[34] = 0.03  # the top speed (0.05) in the later half only
    assert moved() == list(range(30, 35))
    speed[32:38] = 0.001
    speed[5:8], speed[34:37] = 0.02, [0.03, 0.05, 0.03]  # blocks 0 and 3
    assert moved() == list(range(30, 35))
    speed[5:8], speed[34], speed[36] = 0.001, 0.001, 0.001  # one fast row
    assert moved() == []
    speed[32:38] = [0.01, 0.03, 0.05, 0.05, 0.03, 0.01]
    speed[14] = 0.011  # a held row (block 1) above a fifth of the top
    assert moved() == []


def test_seed_159_holds_out_half_its_fast_moves() -> None:
    """Seed 159 of the independent generator: every row above a fifth of the top speed is
    in one block; half of them are held out and the training rows keep the top speed."""
    gen = make_trace("none", 159)
    part = prepare(Trace("indep", gen.time_s, gen.position_m, gen.force_N), "friction",
                   None, EVERY_SAMPLE).main  # fmt: skip
    speed = np.abs(part.kin.velocity_m_s)
    fast = speed >= 0.2 * float(np.max(speed))
    assert 0.3 <= np.sum(fast & part.held) / np.sum(fast) <= 0.7
    assert float(np.max(speed[part.train])) >= 0.8 * float(np.max(speed))
    accel = np.abs(part.kin.acceleration_m_s2)
    assert float(np.max(accel[part.train])) >= 0.8 * float(np.max(accel))


def test_the_held_third_follows_the_starts() -> None:
    """Starts only in the first and last thirds of the blocks: the last third (nearest a
    third of them) is held out; spread over all three, or none at all: the second."""
    dt, blocks = 1e-3, 60
    t = np.arange(blocks * 1000) * dt
    third = (np.arange(t.size) * blocks // t.size) % 3

    def held(start_blocks: list[int]) -> int:
        x = np.zeros_like(t)
        for k, b in enumerate(start_blocks):  # a 1 mm move of 0.2 s from mid-block
            s = np.clip((t - b - 0.5) / 0.2, 0.0, 1.0)
            x += (1.0 if k % 2 == 0 else -1.0) * 1e-3 * s * s * (3.0 - 2.0 * s)
        x = np.round(x / 1e-8) * 1e-8
        kin = kinematics(Trace("synthetic", t, x, np.ones_like(t)), 0.45 / dt)
        still = 0.01 * float(np.max(np.abs(kin.velocity_m_s)))
        return held_third(third, kin, still, 0.6e-8, 1.5e-8, x, SplitConfig())

    assert held([0, 3, 6, 9, 12, 15, 18, 21, 2, 5, 8, 11]) == 2  # 8 / 0 / 4 per third
    assert held([0, 4, 8, 12, 16, 20, 24, 28, 32]) == 1  # 3 / 3 / 3
    assert held([]) == 1


def test_a_hard_stop_is_not_a_reversal() -> None:
    """reversal_transient-132 (a 1.6 nm encoder at 1.5 kHz) stops from 74 mm/s at
    t = 1.86 s and rests for 1 s before going on the same way. The kinematics' zero-phase
    low-pass overshoots the rest by 1.2 nm, more than the 0.6-step deadband: traced on it,
    the path's direction disagreed with the truth's (the sign of its velocity, held
    through standstills) for 0.96 s in a row. Traced on the measured position, as the
    diagnosis does, it disagrees only while a slow turn has not yet retreated by a count."""
    seed = 132
    gen = make_trace("reversal_transient", seed)
    truth = baseline(seed)[0]
    held = np.sign(truth.velocity_m_s)
    for k in range(1, held.size):
        held[k] = held[k] or held[k - 1]
    cfg = EVERY_SAMPLE
    prepared = prepare(Trace("indep", gen.time_s, gen.position_m, gen.force_N), "friction",
                       None, cfg)  # fmt: skip
    part = prepared.main
    ctx = prepared.context(part, np.zeros(gen.time_s.size))
    off = np.flatnonzero((ctx.direction != held) & (ctx.direction != 0.0))
    runs = np.split(off, np.flatnonzero(np.diff(off) > 1) + 1) if off.size else []
    longest_s = max((r.size for r in runs), default=0) / truth.sample_rate_Hz
    assert longest_s < 0.025
    # the premise: the low-pass does overshoot the rest there by more than the deadband
    stop = (gen.time_s > 1.85) & (gen.time_s < 1.9)
    overshoot_m = float(np.max(part.kin.position_m[stop]) - part.kin.position_m[stop][-1])
    assert overshoot_m > prepared.reversal_deadband_m


@pytest.mark.parametrize("seed", [132, 140, 151])
def test_an_axis_ringing_under_its_loop_turns_where_its_command_turns(seed: int) -> None:
    """A closed-loop axis rings after each turn (a force's step under a stiff loop: a
    decaying 200 Hz ring of 60 nm here, above the deadband): with the commanded position
    in the trace, the path turns where the command turns, as often; without it, on the
    ringing position, more often (the premise)."""
    gen = make_trace("reversal_transient", seed)
    t, command = gen.time_s, gen.position_m
    turns = np.flatnonzero(np.diff(np.sign(np.diff(command))) != 0) + 1
    ring = np.zeros_like(t)
    for k in turns:
        after = t[k:] - t[k]
        ring[k:] += 60e-9 * np.exp(-after / 0.01) * np.sin(2 * np.pi * 200.0 * after)
    measured = command + ring
    force = gen.force_N

    def reversals(trace: Trace) -> int:
        prepared = prepare(trace, "friction", None, EVERY_SAMPLE)
        ctx = prepared.context(prepared.main, np.zeros(t.size))
        return int(np.sum(np.abs(np.diff(ctx.direction[ctx.direction != 0.0])) > 0))

    clean = reversals(Trace("indep", t, command, force))
    with_command = Trace("indep", t, measured, force, reference_position_m=command)
    assert reversals(with_command) == clean
    assert reversals(Trace("indep", t, measured, force)) > clean
