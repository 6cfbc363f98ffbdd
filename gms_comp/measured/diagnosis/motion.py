"""Kinematics of a measured trace and the benchmark's signal processing.

Velocity and acceleration come from the measured position the way the EMPS benchmark
(Janot, Gautier, Brunot 2019) derives them: a zero-phase 4th-order Butterworth low-pass
(MATLAB ``filtfilt`` edge padding) and central differences. :func:`decimate_matlab`
reproduces MATLAB's ``decimate`` (Chebyshev-I order 8, forward-backward, the last sample
kept), which the benchmark applies before least squares and before its error norms.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from gms_comp.arrays import FloatArray
from gms_comp.kinematics import Kinematics
from gms_comp.measured.traces import Trace


def filtfilt_matlab(b: FloatArray, a: FloatArray, x: FloatArray) -> FloatArray:
    """Zero-phase filtering with MATLAB's edge padding of 3 x (filter order) samples."""
    return np.asarray(signal.filtfilt(b, a, x, padlen=3 * (max(len(a), len(b)) - 1)))


def decimate_matlab(x: FloatArray, factor: int) -> FloatArray:
    """MATLAB ``decimate(x, factor)``: Chebyshev-I low-pass, zero phase, keep the last sample."""
    b, a = signal.cheby1(8, 0.05, 0.8 / factor)
    y = filtfilt_matlab(b, a, x)
    n_out = -(-len(x) // factor)
    first = factor - (factor * n_out - len(x)) - 1
    return y[first::factor]


def kinematics(
    trace: Trace, cutoff_Hz: float, acceleration_cutoff_Hz: float | None = None
) -> Kinematics:
    """Position low-passed at ``cutoff_Hz`` (zero phase), velocity and acceleration by
    central differences; a measured velocity column is not used, so that position,
    velocity and acceleration share one filter. With ``acceleration_cutoff_Hz`` below
    ``cutoff_Hz`` the acceleration comes from the position low-passed there instead: the
    second difference of a barely filtered encoder position is mostly quantisation (a
    20 nm step at 4 kHz is 0.3 m/s^2), which a mass fitted on it would carry as noise and
    as a bias towards zero."""
    dt = trace.sample_time_s
    x = _lowpass(trace.position_m, cutoff_Hz, dt)
    v = np.gradient(x, dt)
    if acceleration_cutoff_Hz is not None and acceleration_cutoff_Hz < cutoff_Hz:
        slow = _lowpass(trace.position_m, acceleration_cutoff_Hz, dt)
        return Kinematics(trace.time_s, x, v, np.gradient(np.gradient(slow, dt), dt))
    return Kinematics(trace.time_s, x, v, np.gradient(v, dt))


def _lowpass(x: FloatArray, cutoff_Hz: float, dt: float) -> FloatArray:
    """``x`` through a zero-phase 4th-order Butterworth low-pass at ``cutoff_Hz``."""
    b, a = signal.butter(4, min(cutoff_Hz * 2.0 * dt, 0.99))
    return filtfilt_matlab(b, a, x)
