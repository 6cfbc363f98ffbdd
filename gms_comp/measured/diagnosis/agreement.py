"""The shape of an effect made to agree with its fitted size.

Some shape parameters follow from the size itself (a dwell gain's windows are computed
at the gain they raise the limits by: ``Policy.consistent_shape``). A fit on a shape
gives a size, the size implies a shape: :func:`agreed` steps between the two, bounded,
to a fixed point.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TypeVar

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.measured.diagnosis.candidates import Option

# Fixed-point steps that make a shape agree with the size fitted on it, and how far
# apart the two may be for the effect to be kept (a factor). Each step goes halfway (in
# log) to the shape the size implies: a dwell's fitted gain falls as its windows' gain
# rises (slope -0.8 in log near agreement), so full steps oscillate about it (three
# left a factor 1.4); half steps converge in two. Where it does not fall smoothly (an
# element that holds through a presliding run at one gain and slips at a slightly larger
# one: dwell_time-117 of the independent generator, fitted 0.060 at 0.10 and 0.014 at
# 0.11), half steps jumped across it four times; once the steps have gone both ways,
# each bisects (in log) between the nearest gains on either side; the best fit returns.
CONSISTENCY_STEPS = 8
CONSISTENCY_CONVERGED = 1.1

Fitted = TypeVar("Fitted")


def agreed(
    first: Fitted, option: Callable[[Fitted], Option],
    coefficients: Callable[[Fitted], FloatArray], fit: Callable[[Option], Fitted],
) -> Fitted:  # fmt: skip
    """``first`` (an option fitted) with its shape made to agree with its fitted size: at
    most ``CONSISTENCY_STEPS`` steps towards the shape of the effect's own rule
    (:meth:`~gms_comp.measured.policies.Policy.consistent_shape`; halfway, then bisecting
    once it has been passed, see ``CONSISTENCY_STEPS``), each one fitted by ``fit``;
    ``option`` and ``coefficients`` read a fit's option and its own coefficients.
    Returns the first fit that agrees within ``CONSISTENCY_CONVERGED``, else the one
    that agrees best."""
    current = best = first
    best_factor = np.inf
    below: dict[str, float] = {}  # per key: the last value whose agreed value was larger
    above: dict[str, float] = {}  # ... and smaller
    for _ in range(CONSISTENCY_STEPS):
        opt = option(current)
        shape, factor = agreement(opt, coefficients(current))
        if factor < best_factor:
            best, best_factor = current, factor
        if factor <= CONSISTENCY_CONVERGED:
            return current
        for k, v in opt.shape.items():
            if shape[k] != v:
                (below if shape[k] > v else above)[k] = v
        current = fit(Option(opt.effect, _step(opt.shape, shape, below, above)))
    return current if agreement(option(current), coefficients(current))[1] < best_factor else best


def _step(
    shape: Mapping[str, float], agreed: Mapping[str, float], below: Mapping[str, float],
    above: Mapping[str, float],
) -> dict[str, float]:  # fmt: skip
    """The next shape towards agreement: halfway (:func:`halfway`), or for a key that has
    been on both sides of it, the geometric mean of the nearest values on either side."""
    step = halfway(shape, agreed)
    for k in step:
        if below.get(k, 0.0) > 0.0 and above.get(k, 0.0) > 0.0:
            step[k] = float(np.sqrt(below[k] * above[k]))
    return step


def halfway(shape: Mapping[str, float], agreed: Mapping[str, float]) -> dict[str, float]:
    """A step from ``shape`` halfway to ``agreed`` (geometric mean of positive values)."""
    return {
        k: float(np.sqrt(v * agreed[k])) if v > 0 and agreed[k] > 0 else agreed[k]
        for k, v in shape.items()
    }


def agreement(option: Option, coefficients: FloatArray) -> tuple[dict[str, float], float]:
    """The shape that agrees with ``option``'s fitted ``coefficients``, and the largest
    factor between it and ``option``'s shape (1: they agree; a filter always does)."""
    shape = dict(option.shape)
    if option.is_filter:
        return shape, 1.0
    agreed = option.policy.consistent_shape(coefficients, shape)
    factors = [
        max(agreed[k] / shape[k], shape[k] / agreed[k]) if agreed[k] * shape[k] > 0 else
        (1.0 if agreed[k] == shape[k] else np.inf)
        for k in shape
    ]  # fmt: skip
    return agreed, max(factors, default=1.0)
