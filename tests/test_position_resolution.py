"""The diagnosis's encoder: its step whatever the motion, the force noise, and the counts
read back as motion where they would show in the model."""

from __future__ import annotations

import json

import numpy as np
import pytest
from indepgen import baseline, make_trace
from scipy import signal

from gms_comp.app.commands.diagnose import summary
from gms_comp.measured.diagnosis.config import SplitConfig
from gms_comp.measured.diagnosis.encoder import encoder_step, position_resolution
from gms_comp.measured.diagnosis.motion import dequantised
from gms_comp.measured.diagnosis.prepare import force_noise, noise_at_rest
from gms_comp.measured.diagnosis.run import diagnose
from gms_comp.measured.traces import Trace


def test_a_quantised_fast_trace_gives_the_encoder_step() -> None:
    # mostly fast motion (tens of steps per sample) with a little slow creep: the 5th
    # percentile of the steps is many steps, the encoder's step is 39 nm
    rng = np.random.default_rng(3)
    q = 39e-9
    speed = np.where(rng.random(50_000) < 0.97, 2e-6, 1e-8)  # m per sample
    x = np.round(np.cumsum(speed * rng.uniform(0.5, 1.5, speed.size)) / q) * q
    steps = np.abs(np.diff(x))
    assert np.percentile(steps[steps > 0], 5) > 10 * q  # what the percentile alone reads
    assert abs(position_resolution(x) - q) < 1e-15
    assert encoder_step(x) == position_resolution(x)


def test_an_encoder_step_seen_once_in_ten_thousand_steps_is_found_through_a_csv() -> None:
    # a fast trace on a 2.05 nm encoder: steps up to ~6000 counts, 1-5 counts in ~4
    # of 10 000 steps (the independent generator's seed 261: 0.014 % single counts),
    # positions within 50 mm written with a CSV's 12 significant digits
    rng = np.random.default_rng(6)
    q = 2.0512839e-9
    slow = rng.random(100_000) < 4e-4
    speed = np.where(slow, 6e-9, 8e-6) * rng.uniform(0.5, 1.5, slow.size)  # m per sample
    truth = np.cumsum(speed * np.where(np.arange(slow.size) % 12_000 < 6000, 1.0, -1.0))
    x = np.array([float(f"{v:.12g}") for v in np.round(truth / q) * q])
    steps = np.abs(np.diff(x))
    ones = np.count_nonzero(np.abs(steps - q) < 0.05 * q)
    assert 0 < ones < 1e-3 * np.count_nonzero(steps)  # rarer than was required
    assert np.max(np.abs(x)) < 0.05
    assert abs(encoder_step(x) / q - 1.0) < 1e-6
    assert position_resolution(x) == encoder_step(x)


def test_an_unquantised_position_falls_back_to_the_percentile() -> None:
    # a continuous position (no encoder step): no step is a common divisor of the others
    x = np.cumsum(np.random.default_rng(4).normal(0.0, 1e-7, 20_000))
    steps = np.abs(np.diff(x))
    assert position_resolution(x) == np.percentile(steps[steps > 0], 5)
    assert encoder_step(x) == 0.0


def _motion() -> tuple[np.ndarray, np.ndarray]:
    """A true position at 2 kHz (a slow cosine stroke, a stop, a reversal within a count,
    a fast stroke) and its speed in counts per sample for a 20 nm encoder."""
    t = np.arange(40_000) / 2000.0
    slow = 1e-6 * (1.0 - np.cos(2 * np.pi * t / 5.0))  # 0 - 2 um, <= 0.013 counts/sample
    creep = np.where(t < 12.0, 0.0, 2.5e-9 * np.sin(np.pi * (t - 12.0)))  # within a count
    fast = np.where(t < 16.0, 0.0, 2e-4 * np.sin(2 * np.pi * (t - 16.0) / 8.0) ** 2)
    x = np.where(t < 10.0, slow, 0.0) + np.where((t >= 12.0) & (t < 16.0), creep, 0.0) + fast
    return x, np.abs(np.gradient(x)) / 20e-9


def test_counts_read_as_motion_follow_the_truth_between_counts() -> None:
    q = 20e-9
    truth, counts_per_sample = _motion()
    x = np.round(truth / q) * q
    d = dequantised(x, q)
    # never further than half a count from the reading (it is where the axis crossed)
    assert np.max(np.abs(d - x)) <= q / 2 + 1e-18
    slow = (counts_per_sample > 1e-3) & (counts_per_sample < 0.5)
    staircase = np.sqrt(np.mean((x - truth)[slow] ** 2))
    read = np.sqrt(np.mean((d - truth)[slow] ** 2))
    assert staircase == pytest.approx(q / np.sqrt(12), rel=0.05)  # a count's uniform error
    assert read < 0.3 * staircase
    # at a standstill (t 10-12 s, the reading held for 4000 samples) it is the reading
    rest = slice(20_500, 23_500)
    assert np.array_equal(d[rest], x[rest])
    # fast motion (several counts a sample) keeps its readings
    fast = np.flatnonzero(counts_per_sample > 3.0)
    fast = fast[(np.abs(np.diff(x, prepend=x[0]))[fast] > 2 * q)]
    assert fast.size > 1000
    assert np.array_equal(d[fast], x[fast])


def test_counts_read_as_motion_of_a_constant_or_continuous_position() -> None:
    assert np.array_equal(dequantised(np.full(100, 3e-6), 1e-8), np.full(100, 3e-6))
    x = np.linspace(0.0, 1e-3, 1000)
    assert np.array_equal(dequantised(x, 0.0), x)


def test_force_noise_is_the_white_noise_of_a_friction_force() -> None:
    # an independent trace's force: the truth's noise within 2 % on three seeds
    for seed in (101, 108, 119):
        gen = make_trace("none", seed)
        assert force_noise(gen.force_N) == pytest.approx(gen.noise_N, rel=0.02)


@pytest.mark.slow
def test_a_coarse_encoder_is_read_as_motion_and_a_fine_one_is_not() -> None:
    # seed 119: a 27 nm encoder on a stiff, quiet, slow trace (K q / sqrt 12 = 1.37 x the
    # noise by the truth); on its counts the baseline held out 1.23 x the noise and
    # sensor_lowpass was named. Seed 108: 6.6 nm, 0.26 x, read as measured.
    for seed, expected in ((119, "encoder counts read as motion"), (108, "measured")):
        truth, noise, q, _ = baseline(seed)
        ratio = float(np.sum(truth.stiffness_N_per_m)) * q / np.sqrt(12.0) / noise
        gen = make_trace("none", seed)
        doc = json.loads(
            json.dumps(diagnose(Trace("x", gen.time_s, gen.position_m, gen.force_N)).to_json())
        )
        assert doc["baseline"]["encoder_noise_ratio"] == pytest.approx(ratio, rel=0.05)
        assert doc["baseline"]["position"] == expected
        assert doc["effect"] == "none"
        text = summary({**doc, "trace": f"none-{seed}"}, gen.time_s.size, "friction")
        said = "the encoder's counts read as motion" in text
        assert said == (seed == 119)


@pytest.mark.slow
def test_an_effect_far_above_the_noise_does_not_hide_what_the_counts_cost() -> None:
    # seed 119's 27 nm encoder with a 1.1 N offset on a 4.4 N level (noise 0.037 N): the
    # baselines, offset and all, hold out within 1 % of each other on the counts and read
    # as motion; on the counts a sensor_lowpass was kept second to smooth their steps
    gen = make_trace("offset", 119)
    d = diagnose(Trace("offset-119", gen.time_s, gen.position_m, gen.force_N))
    doc = d.to_json()
    assert doc["baseline"]["position"] == "encoder counts read as motion"
    assert [r.effect.name for r in d.ranked] == ["offset"]
    true_offset = dict(gen.effects)["offset"]["offset_N"]
    assert d.ranked[0].effect.parameters()["offset_N"] == pytest.approx(true_offset, rel=0.05)
    # the extended model holds out within 10 % of the force's noise
    assert d.extended_rms_N < 1.1 * gen.noise_N


def test_the_force_noise_at_rest_reads_low_passed_noise_the_differences_miss() -> None:
    # a step-and-stop path on a 10 nm encoder: 0.5 s moves, 0.4 s rests, force noise
    # low-passed at 5 % of the 2 kHz rate (a sensor's filter), 0.07 N standard deviation
    rng = np.random.default_rng(7)
    fs, q = 2000.0, 10e-9
    v = np.concatenate([np.concatenate([np.full(1000, s * 5e-3), np.zeros(800)])
                        for s in (1.0, -1.0) * 10])  # fmt: skip
    x = np.round(np.cumsum(v) / fs / q) * q
    sos = signal.butter(2, 100.0, fs=fs, output="sos")
    coloured = signal.sosfiltfilt(sos, rng.normal(size=x.size))
    coloured *= 0.07 / np.std(coloured)
    force = 3.0 * np.sign(v) + coloured  # a level that holds at rest
    assert force_noise(force) < 0.2 * 0.07  # the second differences see little of it
    assert noise_at_rest(force, x, SplitConfig()) == pytest.approx(0.07, rel=0.1)
    white = 3.0 * np.sign(v) + rng.normal(0.0, 0.07, x.size)
    assert noise_at_rest(white, x, SplitConfig()) == pytest.approx(force_noise(white), rel=0.05)
