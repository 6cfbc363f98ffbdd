"""Kinematics of a measured trace and the benchmark's signal processing.

Velocity and acceleration come from the measured position the way the EMPS benchmark
(Janot, Gautier, Brunot 2019) derives them: a zero-phase 4th-order Butterworth low-pass
(MATLAB ``filtfilt`` edge padding) and central differences (for a diagnosis, the
acceleration over three samples, its position continued past each end);
:func:`decimate_matlab` is MATLAB's ``decimate``, which the benchmark applies.
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


# A diagnosed trace's acceleration comes from its position continued past each end by
# its odd reflection over this many periods of the acceleration's cut-off: MATLAB's pad of
# 3 x the filter order is shorter than the filter's settling, and a trace that ends moving
# rang into the acceleration (twice the true peak at its last samples). Position and
# velocity keep the benchmark's edges.
REFLECTED_PERIODS = 3.0


def kinematics(
    trace: Trace, cutoff_Hz: float, acceleration_cutoff_Hz: float | None = None,
    reflected: bool = True,
) -> Kinematics:  # fmt: skip
    """Position low-passed at ``cutoff_Hz`` (zero phase), velocity and acceleration by
    central differences; a measured velocity column is not used, so that position,
    velocity and acceleration share one filter. With ``acceleration_cutoff_Hz`` below
    ``cutoff_Hz`` the acceleration comes from the position low-passed there instead (the
    second difference of a barely filtered encoder position is mostly quantisation).
    ``reflected``: the acceleration's position continued past the ends first and
    differenced over three samples; without, the benchmark's edges and differences."""
    dt = trace.sample_time_s
    x = _lowpass(trace.position_m, cutoff_Hz, dt)
    v = np.gradient(x, dt)
    slow_Hz = min(cutoff_Hz, acceleration_cutoff_Hz or cutoff_Hz)
    pad = min(int(np.ceil(REFLECTED_PERIODS / (slow_Hz * dt))) + 2, len(trace) - 1)
    pad = pad if reflected else 0
    if pad == 0 and slow_Hz == cutoff_Hz:  # the benchmark's: the velocity's difference
        slow = x
    else:
        slow = _lowpass(_reflected(trace.position_m, pad), slow_Hz, dt)
    a = _second_difference(slow, dt) if reflected else np.gradient(np.gradient(slow, dt), dt)
    return Kinematics(trace.time_s, x, v, a[pad : pad + len(trace)])


def _second_difference(x: FloatArray, dt: float) -> FloatArray:
    """The three-point second difference of ``x`` (the ends repeat their neighbours).

    Its gain at a frequency f is sinc(f dt)^2, 0.97 at a tenth of the sample rate; the
    benchmark's difference of a central difference spans five samples and has
    sinc(2 f dt)^2, 0.87 there, and a mass fitted on it comes out high by what the
    acceleration lost."""
    a = np.empty_like(x)
    a[1:-1] = (x[2:] - 2.0 * x[1:-1] + x[:-2]) / dt**2
    a[0], a[-1] = a[1], a[-2]
    return a


def _reflected(x: FloatArray, pad: int) -> FloatArray:
    """``x`` continued ``pad`` samples past each end by its odd reflection about the end
    sample (a ramp goes on as a ramp)."""
    if pad <= 0:
        return np.asarray(x, dtype=float)
    return np.concatenate([2.0 * x[0] - x[pad:0:-1], x, 2.0 * x[-1] - x[-2 : -pad - 2 : -1]])


def _lowpass(x: FloatArray, cutoff_Hz: float, dt: float) -> FloatArray:
    """``x`` through a zero-phase 4th-order Butterworth low-pass at ``cutoff_Hz``."""
    b, a = signal.butter(4, min(cutoff_Hz * 2.0 * dt, 0.99))
    return filtfilt_matlab(b, a, x)


# A plateau of an encoder's position longer than this many times its neighbours' is a
# stop (or the axis creeping within one count), not a count passed on the way.
HOLD_RATIO = 3.0


def dequantised(position_m: FloatArray, step_m: float) -> FloatArray:
    """An encoder's staircase ``position_m`` (counts of ``step_m``) read back as the
    motion it samples: where the count changes by one, the axis crossed the half-count
    between the two readings half a sample before the second, and moved evenly between
    such crossings; a count held much longer than its neighbours (a stop, a reversal
    within a count) is the position while held, after half the neighbours' crossing
    time. Changes of several counts in a sample (fast motion) keep their readings."""
    x = np.asarray(position_m, dtype=float)
    n = x.size
    change = np.flatnonzero(np.diff(x) != 0.0)
    if change.size == 0 or step_m <= 0.0:
        return x.copy()
    counts = np.round((x[change + 1] - x[change]) / step_m)
    single = np.abs(counts) == 1.0
    first = np.concatenate([[0], change + 1])  # the plateaus of one reading
    last = np.concatenate([change, [n - 1]])
    length = (last - first + 1).astype(float)
    # a plateau is passed through between two one-count changes the same way, not
    # much longer than its neighbours
    before = np.concatenate([[False], single])
    after = np.concatenate([single, [False]])
    same_way = np.concatenate([[False], np.sign(counts[:-1]) == np.sign(counts[1:]), [False]])
    neighbours = np.concatenate([[0.0], np.maximum(length[:-2], length[2:]), [0.0]])
    held = np.flatnonzero(~(before & after & same_way & (length <= HOLD_RATIO * neighbours)))
    # a held plateau's value from half its neighbours' crossing time in (else its middle)
    lead = np.where(before, np.concatenate([[1.0], length[:-1]]) / 2.0, 0.5)[held]
    trail = np.where(after, np.concatenate([length[1:], [1.0]]) / 2.0, 0.5)[held]
    start = first[held] - 0.5 + lead
    end = last[held] + 0.5 - trail
    middle = (first[held] + last[held]) / 2.0
    crossed = start >= end
    start = np.where(crossed, middle, np.maximum(start, first[held]))
    end = np.where(crossed, middle, np.minimum(end, last[held]))
    jumps = change[~single]
    knot_t = np.concatenate([
        [0.0, n - 1.0], change[single] + 0.5, jumps, jumps + 1.0, start, end,
    ])  # fmt: skip
    knot_x = np.concatenate([
        x[[0, n - 1]], (x[change[single]] + x[change[single] + 1]) / 2.0, x[jumps],
        x[jumps + 1], x[first[held]], x[first[held]],
    ])  # fmt: skip
    order = np.argsort(knot_t, kind="stable")
    knot_t, knot_x = knot_t[order], knot_x[order]
    distinct = np.concatenate([[True], np.diff(knot_t) > 0.0])
    return np.interp(np.arange(n, dtype=float), knot_t[distinct], knot_x[distinct])
