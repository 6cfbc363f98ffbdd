"""The criterion: whether an extension is worth keeping (docs/diagnosis-method.md, section 2).

One rule for every effect, every step: fitted on the training rows, it must lower the
held-out error of the model it extends by a relative margin, or by a smaller one that is
significant against the residual's own spread (:func:`lowers`); an effect acting on few
rows is judged where it acts, every event predicted by a fit that left it out
(:func:`lowers_locally`); where its policy names the rows that tell it apart, there too;
and it must be large enough to matter and within the ranges its effect declares, those a
table's extension is checked against (:func:`admissible`). A shape that follows the
effect's size (a dwell gain's windows) must agree with it (:func:`agreed` steps the two
together to a fixed point).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TypeVar

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.measured.diagnosis.candidates import Option, Scorer, Trial, acts_locally
from gms_comp.measured.diagnosis.config import DiagnosisConfig, SelectionConfig
from gms_comp.measured.diagnosis.design import rms
from gms_comp.runtime.effects import Effect, ExtensionError, effect_from_dict, effect_to_dict

# Fixed-point steps that make a shape agree with the size fitted on it: each goes halfway
# (in log) to the shape the size implies (a dwell's fitted gain falls as its windows' gain
# rises, and full steps oscillate); once the steps have gone both ways (an element that
# slips at one gain and not at a slightly smaller one), each bisects between the nearest
# values on either side; the best fit returns. Converged within CONSISTENCY_CONVERGED.
CONSISTENCY_STEPS = 8
CONSISTENCY_CONVERGED = 1.1


def significance(current: FloatArray, new: FloatArray, chunks: int) -> float:
    """z statistic of the drop in squared residual, its spread from contiguous chunks.

    With ``d = current - new`` (what the trial changes), the drop is
    ``sum(current**2 - new**2) = sum(2 new d + d**2)``; where the trial is right, ``new``
    is the noise and the drop's chance part is ``2 sum(new d)``, whose spread is taken
    over contiguous chunks (residuals are correlated in time, chunks much less so). Unlike
    a t test of the chunks' gains, this does not cap an effect that acts in a few chunks
    only (fast moves, break-aways) at the square root of their number."""
    n = min(chunks, current.size // 2)
    if n < 2:
        return 0.0
    change = current - new
    drop = float(np.sum(current**2 - new**2))
    cross = np.array([np.sum(c) for c in np.array_split(new * change, n)])
    spread = 2.0 * float(np.sqrt(np.sum(cross**2)))
    return drop / spread if spread > 0 else (np.inf if drop > 0 else 0.0)


def lowers(rules: SelectionConfig, current: FloatArray, new: FloatArray) -> bool:
    """Whether the held-out residual ``new`` is worth an effect against ``current``: its
    RMS lower by the margin, or by the small margin and significant."""
    rms0, rms1 = rms(current), rms(new)
    z = rules.significance_t
    return rms1 <= (1.0 - rules.margin) * rms0 or (
        rms1 <= (1.0 - rules.small_margin) * rms0
        and significance(current, new, rules.significance_chunks) >= z
    )


def lowers_locally(
    rules: SelectionConfig, current: FloatArray, new: FloatArray, noise_N: float
) -> bool:
    """Whether an effect that acts on few rows is worth keeping, judged there
    (``current``, ``new``: the residuals at those rows without and with it, every event
    by a fit that left it out): significant (``local_significance_t``), and lowering
    what those rows hold above the force's noise ``noise_N`` (the RMS with the noise's
    share taken out) by ``local_margin`` (the RMS itself, noise included, hides a gain
    that stands far out of the noise at a few starts)."""
    if current.size == 0:
        return False
    above0, above1 = (np.sqrt(max(rms(r) ** 2 - noise_N**2, 0.0)) for r in (current, new))
    return (
        above0 > 0.0
        and above1 <= (1.0 - rules.local_margin) * above0
        and significance(current, new, rules.significance_chunks) >= rules.local_significance_t
    )


def admissible(
    cfg: DiagnosisConfig, scorer: Scorer, trial: Trial, level_N: float, noise_N: float
) -> bool:
    """Whether ``trial`` is worth an effect (see the module docstring)."""
    rms0, held0 = scorer.heldout_rms_N, scorer.held_residual_N
    rules = cfg.selection
    local = acts_locally(trial, rules)
    if trial.heldout_rms_N >= rms0 and not local:
        return False
    worth = lowers(rules, held0, trial.held_residual_N)
    if not worth and local:
        # judged where it acts, at every event by a fit without it: an effect at a few
        # events may have none or one held out (and the held-out RMS not lowered)
        judge = scorer.judge  # on every sample
        local0, local1 = judge.left_out(trial)
        worth = lowers_locally(rules, local0, local1, noise_N)
    apart = scorer.told_apart(trial.option)
    if worth and apart is not None:
        # and where the motion tells it from the effects it could stand in for
        worth = bool(np.any(apart)) and lowers(rules, held0[apart], trial.held_residual_N[apart])
    if not worth or not consistent(scorer, trial):
        return False
    if not trial.option.is_filter:
        # an effect sized against the friction it scales (a dwell's break-away gain)
        m = scorer.theta.size
        effect = trial.option.effect.from_coefficients(trial.theta[m:], trial.option.shape)
        if not declared(effect):
            return False  # a table could not hold it (a dwell gain of 2e5)
        size = trial.option.policy.relative_size(effect, scorer.parts[0].ctx)
        if size is not None and size < rules.min_effect_fraction:
            return False
    return float(np.max(np.abs(scorer.change(trial)))) >= rules.min_effect_fraction * level_N


def declared(effect: Effect) -> bool:
    """Whether ``effect``'s parameters lie in the ranges its class declares."""
    try:
        effect_from_dict(effect_to_dict(effect))
    except ExtensionError:
        return False
    return True


def consistent(scorer: Scorer, trial: Trial) -> bool:
    """Whether ``trial``'s shape agrees with its size within ``consistent_within``."""
    return _agreement(scorer, trial)[1] <= scorer.rules.consistent_within


def _agreement(scorer: Scorer, trial: Trial) -> tuple[dict[str, float], float]:
    """The shape that agrees with ``trial``'s fitted size, and the largest factor
    between it and ``trial``'s (1: they agree; a filter always does)."""
    return agreement(trial.option, trial.theta[scorer.theta.size :])


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
