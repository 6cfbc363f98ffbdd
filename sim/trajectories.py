"""Reference trajectories sampled at the servo rate, with velocity and acceleration.

Every trajectory is built from a raw velocity profile that is passed through
two moving-average (FIR) filters, the drives' usual trajectory smoothing: the
first bounds the acceleration (peak velocity / first window), the second the
jerk. A boxcar keeps the integral of the velocity, so the filtered profile
travels the same distance and keeps exact standstills between moves. Position
is the trapezoidal integral of the filtered velocity, acceleration its central
difference. A dwell at the end lets the
axis settle, so every run ends with a stop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from gms_comp.arrays import FloatArray
from gms_comp.kinematics import Kinematics
from gms_comp.physics.profiles import seed_fig7_profile


@dataclass(frozen=True)
class Reference:
    """A sampled reference: position, velocity and acceleration per servo cycle."""

    period_s: float
    position_m: FloatArray
    velocity_m_s: FloatArray
    acceleration_m_s2: FloatArray

    @property
    def time_s(self) -> FloatArray:
        """Sample times."""
        return np.arange(self.position_m.size, dtype=np.float64) * self.period_s

    @property
    def cycles(self) -> int:
        """Number of samples."""
        return int(self.position_m.size)

    @property
    def duration_s(self) -> float:
        """Length of the trajectory."""
        return self.cycles * self.period_s

    @property
    def kinematics(self) -> Kinematics:
        """The reference as the one kinematics record, on its sample times."""
        return Kinematics(self.time_s, self.position_m, self.velocity_m_s, self.acceleration_m_s2)


def from_velocity(
    velocity_m_s: FloatArray,
    period_s: float,
    acceleration_window_s: float,
    jerk_window_s: float,
    dwell_s: float,
    start_m: float = 0.0,
) -> Reference:
    """Smooth a raw velocity profile and integrate it into a :class:`Reference`."""
    windows = [max(1, round(w / period_s)) for w in (acceleration_window_s, jerk_window_s)]
    padded = np.concatenate([velocity_m_s, np.zeros(sum(windows) + round(dwell_s / period_s))])
    v = padded
    for w in windows:
        # Full convolution truncated to the input length: causal, delays by w/2.
        v = np.convolve(v, np.full(w, 1.0 / w))[: padded.size]
    # Trapezoidal position and central-difference acceleration: both second-order
    # consistent with the velocity samples, so the feedforward does not fight the loop.
    x = start_m + np.concatenate([[0.0], np.cumsum(v[:-1] + v[1:]) * (period_s / 2)])
    a = np.gradient(v, period_s)
    return Reference(period_s, x, v, a)


def sine(
    amplitude_m: float,
    frequency_Hz: float,
    periods: float,
    period_s: float,
    acceleration_window_s: float,
    jerk_window_s: float,
    dwell_s: float,
) -> Reference:
    """Sinusoidal reversals ``x = A sin(2 pi f t)``, started at full speed through 0."""
    w = 2 * math.pi * frequency_Hz
    t = np.arange(round(periods / frequency_Hz / period_s)) * period_s
    return from_velocity(
        amplitude_m * w * np.cos(w * t), period_s, acceleration_window_s, jerk_window_s, dwell_s
    )


def circle(
    radius_m: float,
    feed_m_s: float,
    revolutions: float,
    period_s: float,
    acceleration_window_s: float,
    jerk_window_s: float,
    dwell_s: float,
) -> tuple[Reference, Reference]:
    """Both axes of a circularity test, run counter-clockwise from the bottom point.

    ``x = R sin(w t)``, ``y = R (1 - cos(w t))`` with ``w = feed / R``: the x axis
    reverses at the quadrant changes at 90 and 270 degrees, at ``a = feed^2 / R``.
    The same filter on both axes smooths the path itself.
    """
    w = feed_m_s / radius_m
    t = np.arange(round(revolutions * 2 * math.pi / w / period_s)) * period_s
    smooth = (period_s, acceleration_window_s, jerk_window_s, dwell_s)
    return (
        from_velocity(feed_m_s * np.cos(w * t), *smooth),
        from_velocity(feed_m_s * np.sin(w * t), *smooth),
    )


def step_stop(
    period_s: float, acceleration_window_s: float, jerk_window_s: float, dwell_s: float
) -> Reference:
    """The seed's Fig. 7 profile (0 -> 1 mm in 0.1 mm steps with stops, and back)."""
    _t, x, _v = seed_fig7_profile(sample_rate_Hz=1.0 / period_s)
    # The step lengths are exact in the positions; differencing them keeps the travel.
    v = np.diff(np.asarray(x, dtype=float), append=x[-1]) / period_s
    return from_velocity(v, period_s, acceleration_window_s, jerk_window_s, dwell_s)


def reversals(reference: Reference) -> NDArray[np.intp]:
    """Indices where the reference velocity changes sign (standstills in between allowed)."""
    moving = np.flatnonzero(reference.velocity_m_s != 0.0)
    signs = np.sign(reference.velocity_m_s[moving])
    return moving[1:][signs[1:] != signs[:-1]]


def stops(reference: Reference, min_stop_s: float) -> list[tuple[int, int]]:
    """Standstill intervals ``[start, end)`` of at least ``min_stop_s`` after a motion."""
    still = reference.velocity_m_s == 0.0
    edges = np.flatnonzero(np.diff(still.astype(np.int8)))
    starts = edges[still[edges + 1]] + 1
    found = []
    for start in starts:
        rest = np.flatnonzero(~still[start:])
        end = int(start + rest[0]) if rest.size else reference.cycles
        if (end - start) * reference.period_s >= min_stop_s:
            found.append((int(start), end))
    return found
