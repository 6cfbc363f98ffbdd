"""Displacement profiles used to exercise the friction models."""

from __future__ import annotations

import numpy as np

from gms_comp.arrays import FloatArray


def piecewise_constant_velocity(
    segments: list[tuple[float, float]], sample_rate_Hz: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Sample a motion made of (duration_s, velocity_m_s) segments, starting at x = 0.

    Positions are exact (integrated segment by segment); the velocity of a
    sample is that of the segment the sample time falls in.
    """
    durations = np.array([d for d, _ in segments], dtype=float)
    velocities = np.array([v for _, v in segments], dtype=float)
    if np.any(durations <= 0.0) or not sample_rate_Hz > 0.0:
        raise ValueError("segment durations and the sample rate must be > 0")
    edges = np.concatenate([[0.0], np.cumsum(durations)])
    starts = np.concatenate([[0.0], np.cumsum(durations * velocities)])
    n = int(np.floor(edges[-1] * sample_rate_Hz + 1e-9)) + 1
    t = np.arange(n) / sample_rate_Hz
    k = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, len(segments) - 1)
    x = starts[k] + velocities[k] * (t - edges[k])
    return t, x, velocities[k]


def seed_fig7_profile(
    sample_rate_Hz: float = 10_000.0,
    *,
    velocity_m_s: float = 0.01,
    step_m: float = 1e-4,
    steps: int = 10,
    dwell_s: float = 0.05,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The seed's Fig. 7: 0 -> 1 mm in 0.1 mm steps at 10 mm/s, a stop after each, and back.

    Returns ``(t_s, x_m, v_m_s)``. The motion starts with a dwell at rest;
    every step of ``step_m`` at constant ``velocity_m_s`` is followed by a stop
    of ``dwell_s`` (the seed's stops are short; their length does not enter the
    rate-independent ball model). 2 x ``steps`` x ``step_m`` of travel in all.
    """
    move_s = step_m / velocity_m_s
    segments = [(dwell_s, 0.0)]
    for direction in (1.0, -1.0):
        for _ in range(steps):
            segments += [(move_s, direction * velocity_m_s), (dwell_s, 0.0)]
    return piecewise_constant_velocity(segments, sample_rate_Hz)
