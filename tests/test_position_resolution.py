"""The diagnosis's position resolution: the encoder's step, whatever the motion."""

from __future__ import annotations

import numpy as np

from gms_comp.measured.diagnosis.prepare import position_resolution


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


def test_an_unquantised_position_falls_back_to_the_percentile() -> None:
    # a continuous position (no encoder step): no step is a common divisor of the others
    x = np.cumsum(np.random.default_rng(4).normal(0.0, 1e-7, 20_000))
    steps = np.abs(np.diff(x))
    assert position_resolution(x) == np.percentile(steps[steps > 0], 5)
