"""The position sensor's step: an encoder's count when the steps are whole multiples of
one, else the 5th percentile of the steps (the diagnosis's position resolution: the free
GMS's smallest break-away, the reversal dead band and the rest band are set from it)."""

from __future__ import annotations

import numpy as np

from gms_comp.arrays import FloatArray

# An encoder's step: the smallest nonzero steps (the first STEP_CANDIDATES distinct ones,
# STEP_TOLERANCE apart, among the smallest 5 %) are tried in turn, each refined from the
# steps of at most STEP_REFINE_COUNTS counts, then of STEP_CHECKED_COUNTS (a CSV's 12
# digits put a fraction of a count on a step of thousands of them); the step is the
# first that QUANTISED_SHARE of those steps are whole multiples of, within
# STEP_TOLERANCE, from STEP_MIN_CHECKED of them or more, however rare one count is (a
# fast trace's single counts may be 0.01 % of its steps).
STEP_CANDIDATES = 8
STEP_REFINE_COUNTS = 20
STEP_CHECKED_COUNTS = 1000
STEP_MIN_CHECKED = 20
STEP_TOLERANCE = 0.05
QUANTISED_SHARE = 0.9


def position_resolution(position_m: FloatArray) -> float:
    """The smallest position step the sensor reports: the encoder's step
    (:func:`encoder_step`), else the 5th percentile of the nonzero steps (the percentile
    alone reads a fast trace's encoder 4-38 x too coarse)."""
    return step_and_resolution(position_m)[1]


def encoder_step(position_m: FloatArray) -> float:
    """The encoder's step when the position's steps are whole multiples of one (one of
    the smallest steps, see ``STEP_CANDIDATES``); 0 when they are not."""
    return step_and_resolution(position_m)[0]


def step_and_resolution(position_m: FloatArray) -> tuple[float, float]:
    """:func:`encoder_step` and :func:`position_resolution` from the position's steps."""
    steps = np.abs(np.diff(position_m))
    steps = steps[steps > 0]
    if steps.size == 0:
        return 0.0, 0.0
    percentile = float(np.percentile(steps, 5))
    tried = 0
    last = 0.0
    for candidate in np.unique(steps[steps <= percentile]):
        if candidate <= last * (1 + STEP_TOLERANCE):
            continue  # the same step again, read through the file's rounding
        last, tried = float(candidate), tried + 1
        if tried > STEP_CANDIDATES:
            break
        step = _refined(steps, float(candidate), STEP_REFINE_COUNTS)
        checked = steps[steps <= (STEP_CHECKED_COUNTS + 0.5) * step]
        if checked.size < STEP_MIN_CHECKED:
            continue
        step = _refined(checked, step, STEP_CHECKED_COUNTS)
        counts = checked / step
        if np.mean(np.abs(counts - np.round(counts)) <= STEP_TOLERANCE) >= QUANTISED_SHARE:
            return step, step
    return 0.0, percentile


def _refined(steps: FloatArray, step: float, most_counts: float) -> float:
    """``step`` refined from the ``steps`` of at most ``most_counts`` counts of it."""
    near = steps[steps <= (most_counts + 0.5) * step]
    return float(np.sum(near) / max(float(np.sum(np.round(near / step))), 1.0))
