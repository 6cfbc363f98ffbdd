"""Stage 4: forward selection of catalogue effects by the criterion (:mod:`.criterion`).

Each round scores every remaining effect over its policy's shape grid on the design of the
effects kept so far, refines the best shape of each by a bounded local search (an effect
acting at few events: from all of them, its shape agreeing with its size), and keeps the
one worth keeping with the lowest held-out RMS. In the first ``free_level_rounds`` rounds
an effect whose policy says so (``free_level``) is also scored with the baseline's slip
level free (:mod:`.level`); where that wins, the selection goes on from that level. After
each effect kept, the GMS force the effects scale is the one fitted beside it. Every search
is bounded: rounds by ``max_effects``, grids by the policies, local search by
``REFINE_STEPS`` (or the policy's ``shape_steps``) x ``MAX_PASSES`` inside its bounds.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.measured.diagnosis.baseline import (
    Baseline,
    FittedPart,
    placed_on,
    refit_gms_force,
)
from gms_comp.measured.diagnosis.candidates import (
    Option,
    Scorer,
    Trial,
    acts_locally,
    best_held_out,
    options,
)
from gms_comp.measured.diagnosis.config import DiagnosisConfig
from gms_comp.measured.diagnosis.criterion import admissible, agreed, agreement, consistent, lowers
from gms_comp.measured.diagnosis.design import rms
from gms_comp.measured.diagnosis.level import (
    FreeLevel,
    with_free_level,
)
from gms_comp.measured.policies import POLICIES, policy
from gms_comp.runtime.effects import Effect

# Relative steps of the local search on shape parameters after the grid, and the most
# passes over the parameters at each step.
REFINE_STEPS = (1.3, 1.08)
MAX_PASSES = 4
# An effect acting locally has its shape from the LOCAL_STARTS best of its grid.
LOCAL_STARTS = 3
# A policy's discrete keys (a filter's order, a dwell gain's form) are not stepped: an
# effect judged where it acts searches each value's shape (one worth an effect first,
# then by held-out RMS); else, where the grid's best lowers the held-out RMS by the
# margin, each value's best grid trial is refined (a coarse grid picks a filter's order
# by which grid point falls nearer its delay; refined, each order's cut-off decides).

Progress = Callable[[str], None]


@dataclass(frozen=True)
class Selection:
    """The output of :func:`select`: the kept options in the order taken, the held-out
    RMS after each, the best trial of every effect in the last round (for the report:
    what was tried and not kept), and the baseline before a Stribeck kept with the
    slip level free moved it (None if none did); the first round's design held-out RMS
    and admissible trials (what came near the first effect kept: a caveat)."""

    baseline: Baseline
    chosen: tuple[Option, ...]
    heldout_rms_N: tuple[float, ...]
    last_round: tuple[Trial, ...]
    level_from: Baseline | None = None
    first_round: tuple[float, tuple[Trial, ...]] = (0.0, ())
    # the level-free grid's baselines fitted so far (a cache, for a selection resumed)
    levels: dict[tuple[float, float], Baseline] = field(default_factory=dict, compare=False)
    # the coefficients of the last kept trial, whose GMS force the next round scales
    gms_theta: FloatArray | None = field(default=None, compare=False)


def local_search(
    opt: Option, cost: Callable[[Option], float], start_cost: float,
    bounds: dict[str, tuple[float, float]], fixed: tuple[str, ...] = (),
    steps: tuple[float, ...] | None = None,
) -> tuple[Option, float]:  # fmt: skip
    """Bounded local search on ``opt``'s shape parameters but ``fixed`` (relative
    ``steps`` shrinking from the grids' spacing, ``REFINE_STEPS`` unless given, each
    value kept inside ``bounds``, at most ``MAX_PASSES`` passes per step), so that they
    are not limited to the grid."""
    best, best_cost = opt, start_cost
    for step in steps or REFINE_STEPS:
        for _ in range(MAX_PASSES):
            improved = False
            for key in opt.shape:
                if key in opt.policy.discrete or key in fixed:
                    continue
                lo, hi = bounds.get(key, (0.0, np.inf))
                for factor in (1.0 / step, step):
                    value = float(np.clip(best.shape[key] * factor, lo, hi))
                    if value == best.shape[key]:
                        continue
                    trial = best.with_value(key, value)
                    trial_cost = cost(trial)
                    if trial_cost < best_cost:
                        best, best_cost, improved = trial, trial_cost, True
            if not improved:
                break
    return best, best_cost


def select(
    baseline: Baseline, cfg: DiagnosisConfig, progress: Progress | None = None,
    start: Selection | None = None,
) -> Selection:  # fmt: skip
    """Forward selection of catalogue effects (see the module docstring); from the
    rounds of ``start`` where given (``baseline``'s selection stopped by a smaller
    ``max_effects``), as if it had not stopped."""
    was = start or Selection(baseline, (), (), ())
    kind = baseline.prepared.force_kind
    pool = [p.effect for p in POLICIES.values() if kind in p.force_kinds]
    chosen, history, last = list(was.chosen), list(was.heldout_rms_N), list(was.last_round)
    pool = [e for e in pool if e not in {o.effect for o in chosen}]
    baseline, level_from, first, levels = was.baseline, was.level_from, was.first_round, was.levels
    gms_theta, placed = was.gms_theta, _placed(baseline)
    parts, every = _gms_from(baseline, gms_theta, placed)
    level = (level_from or baseline).sliding_force_N
    noise = baseline.prepared.noise_N
    while pool and len(chosen) < cfg.max_effects:
        scorer = Scorer(parts, chosen, cfg.selection, every)
        last = []
        for i, effect in enumerate(pool):
            if progress:
                progress(f"round {len(chosen) + 1}: {effect.name} ({i + 1}/{len(pool)})")
            trials = scorer.score_all(options(effect, scorer, baseline.presliding_m))
            if not trials:
                continue
            best = best_held_out(scorer.theta.size, trials, cfg.selection)
            if acts_locally(best, cfg.selection):
                # its shape from all its events (the held-out rows may hold one or none),
                # each form's apart: the forms worth an effect first, then held out
                shaped = [_local_shape(scorer, f, baseline.presliding_m) for f in _forms(trials)]
                best = min(shaped, key=lambda t: (not admissible(cfg, scorer, t, level, noise),
                                                  t.heldout_rms_N))  # fmt: skip
            elif best.heldout_rms_N < scorer.heldout_rms_N:
                # each order refined only where the effect could be kept by its margin
                # alone (each is a local search: 10 % of a typical trace's time)
                big = best.heldout_rms_N <= (1.0 - cfg.selection.margin) * scorer.heldout_rms_N
                starts = _per_value(trials) if big else [best]
                refined = [_refine(scorer, t, baseline.presliding_m) for t in starts]
                best = _consistent(scorer, min(refined, key=lambda t: t.heldout_rms_N))
            last.append(best)
        kept = [t for t in last if admissible(cfg, scorer, t, level, noise)]
        first = first if chosen else (scorer.heldout_rms_N, tuple(kept))
        take = min(kept, key=lambda t: t.heldout_rms_N) if kept else None
        # an effect at another slip level (where taken at the baseline's level, the
        # refit searches its level)
        for effect in (
            (e for e in pool if policy(e).free_level)
            if len(chosen) < cfg.selection.free_level_rounds
            else ()
        ):
            if take is not None and take.option.effect is effect:
                break
            free = _free_level(cfg, effect, baseline, scorer, last, level, levels)
            if free is not None:
                # the selection goes on from that level
                level_from = level_from or baseline
                baseline, take = free.baseline, free.trial
                placed = _placed(baseline)
                last = [take if t.option.effect is effect else t for t in last]
                if not chosen:  # the first round's near tie is judged against it
                    others = (t for t in first[1] if t.option.effect is not effect)
                    first = (first[0], (*others, take))
                break
        if take is None:
            break
        chosen.append(take.option)
        history.append(take.heldout_rms_N)
        pool.remove(take.option.effect)
        gms_theta = take.theta
        parts, every = _gms_from(baseline, gms_theta, placed)
    return Selection(
        baseline, tuple(chosen), tuple(history), tuple(last), level_from, first, levels,
        gms_theta,
    )  # fmt: skip


Placed = Callable[[], tuple[FittedPart, ...]]


def _placed(baseline: Baseline) -> Placed | None:
    """``baseline``'s parts along every sample (placed when first asked), if it is
    fitted on every k-th sample; else None."""
    full = baseline.prepared.every_sample
    return None if full is None else functools.cache(lambda: placed_on(full, baseline).parts)


def _gms_from(
    baseline: Baseline, theta: FloatArray | None, placed: Placed | None
) -> tuple[tuple[FittedPart, ...], Placed | None]:
    """``baseline``'s parts with the GMS force (and elements) of the coefficients
    ``theta`` (a joint fit with the effects kept; None: the baseline's own), and the
    same along every sample (``placed``, its GMS force refitted when first asked).
    The effects that scale the GMS force scale the one fitted beside the kept effects (the
    baseline fitted alone takes part of a large offset into its limits)."""
    basis = baseline.basis

    def gms(parts: tuple[FittedPart, ...]) -> tuple[FittedPart, ...]:
        return parts if theta is None else refit_gms_force(parts, theta, basis)

    every = None if placed is None else functools.cache(lambda: gms(placed()))
    return gms(baseline.parts), every


def _free_level(
    cfg: DiagnosisConfig, effect: type[Effect], baseline: Baseline, scorer: Scorer,
    rivals: Sequence[Trial], level_N: float, fitted: dict[tuple[float, float], Baseline],
) -> FreeLevel | None:  # fmt: skip
    """``effect`` with the slip level free (:mod:`.level`), shape refined, if it is worth
    keeping on its level and lowers, by the criterion (:func:`~.criterion.lowers`), the
    held-out residual of the design so far and of every other effect's best trial of the
    round, both also on its level and where the design without it fits best on the grid:
    a level's gain alone is not the effect's."""
    free = with_free_level(effect, baseline, scorer, fitted)
    if free is None or free.trial.heldout_rms_N >= free.scorer.heldout_rms_N:
        return None
    trial = _consistent(free.scorer, _refine(free.scorer, free.trial, free.baseline.presliding_m))
    others = [t for t in rivals if t.option.effect is not effect]
    here = [scorer.held_residual_N, *(t.held_residual_N for t in others)]
    levels = [free.scorer] if free.plain is free.scorer else [free.scorer, free.plain]
    there = [s.held_residual_N for s in levels]
    there += [s.score(t.option).held_residual_N for s in levels for t in others]
    if not lowers(cfg.selection, min(here + there, key=rms), trial.held_residual_N):
        return None
    if not admissible(cfg, free.scorer, trial, level_N, baseline.prepared.noise_N):
        return None
    return dataclasses.replace(free, trial=trial)


def _per_value(trials: Sequence[Trial]) -> list[Trial]:
    """The best trial of each value of the policy's discrete keys."""
    return [min(f, key=lambda t: t.heldout_rms_N) for f in _forms(trials)]


def _forms(trials: Sequence[Trial]) -> list[list[Trial]]:
    """``trials`` by the values of their policy's discrete keys, in order."""
    forms: dict[tuple[float, ...], list[Trial]] = {}
    for t in trials:
        key = tuple(t.option.shape[k] for k in t.option.policy.discrete if k in t.option.shape)
        forms.setdefault(key, []).append(t)
    return list(forms.values())


def _refine(scorer: Scorer, best: Trial, presliding_m: float) -> Trial:
    trials: dict[int, Trial] = {}

    def cost(opt: Option) -> float:
        trial = scorer.score(opt)
        trials[id(opt)] = trial
        return trial.heldout_rms_N

    rules, ctx = best.option.policy, scorer.parts[0].ctx
    bounds = rules.shape_bounds(ctx, presliding_m)
    opt, _ = local_search(best.option, cost, best.heldout_rms_N, bounds, (), rules.shape_steps(ctx))
    return best if opt is best.option else trials[id(opt)]


def _local_shape(scorer: Scorer, trials: Sequence[Trial], presliding_m: float) -> Trial:
    """The shape of an effect at a few events, from all of them: each of the grid's
    shapes made to agree with its fitted size (:func:`agreed`; from the grid's shape
    nearest agreement), the best by :meth:`~.candidates.Scorer.whole_rms`, then a bounded
    local search of the keys its size does not set, then :func:`_polish` within the
    agreement factor. The grid's sizes are only starts: a dwell gain's size and time
    constant trade along a ridge, and a grid point off agreement lay off it (tau 0.5 s
    at a gain of 0.1 for a true 0.06 s and 0.05)."""
    m = scorer.theta.size
    rules = trials[0].option.policy
    settled: dict[tuple[tuple[str, float], ...], Trial] = {}

    def settle(opt: Option) -> Trial:
        key = _shape_key(opt)
        if key not in settled:
            first = scorer.score(opt)
            settled[key] = agreed(first, lambda t: t.option, lambda t: t.theta[m:], scorer.score)
        return settled[key]

    def cost(opt: Option) -> float:
        # a shape that cannot be made to agree is not a candidate: its effect would not
        # be kept, and on dwell_time-117 the search ended at one (tau 0.97 s, the fitted
        # gain twice the windows') beside shapes that agree
        trial = settle(opt)
        return scorer.whole_rms(trial.option) if consistent(scorer, trial) else np.inf

    free = [k for k in rules.effect.SHAPE if k not in rules.set_by_size]
    starts: dict[tuple[float, ...], Trial] = {}
    for t in sorted(trials, key=lambda t: agreement(t.option, t.theta[m:])[1]):
        starts.setdefault(tuple(t.option.shape[k] for k in free), t)
    # settled: the LOCAL_STARTS best as they are (settling costs up to four fits each)
    ranked = sorted(starts.values(), key=lambda t: scorer.whole_rms(t.option))
    start = min((t.option for t in ranked[:LOCAL_STARTS]), key=cost)
    bounds = rules.shape_bounds(scorer.parts[0].ctx, presliding_m)
    opt, _ = local_search(start, cost, cost(start), bounds, rules.set_by_size)
    return _polish(scorer, [settle(opt), *trials], bounds)


def _polish(
    scorer: Scorer, trials: Sequence[Trial], bounds: dict[str, tuple[float, float]]
) -> Trial:
    """The best of ``trials`` by :meth:`~.candidates.Scorer.whole_rms` among those whose
    shape agrees with their size within ``consistent_within`` (the first when none
    does), then a bounded local search of every key, the size-set ones too, over shapes
    that stay within that agreement (settling each shape to exact agreement walks down
    the gain where the column is attenuated against the truth's). For an effect whose
    size sets no key, this is the local search again from the best consistent trial."""
    scored: dict[tuple[tuple[str, float], ...], Trial] = {}

    def fitted(opt: Option) -> Trial:
        key = _shape_key(opt)
        if key not in scored:
            scored[key] = scorer.score(opt)
        return scored[key]

    def cost(opt: Option) -> float:
        return scorer.whole_rms(opt) if consistent(scorer, fitted(opt)) else np.inf

    agreeing = [t for t in trials if consistent(scorer, t)]
    if not agreeing:
        return trials[0]
    start_cost, start = min(((scorer.whole_rms(t.option), t) for t in agreeing), key=lambda p: p[0])
    scored[_shape_key(start.option)] = start
    opt, _ = local_search(start.option, cost, start_cost, bounds)
    return fitted(opt)


def _shape_key(opt: Option) -> tuple[tuple[str, float], ...]:
    """``opt``'s shape as a hashable key."""
    return tuple(sorted(opt.shape.items()))


def _consistent(scorer: Scorer, trial: Trial) -> Trial:
    """``trial`` with its shape made to agree with its fitted size (:func:`agreed`)."""
    m = scorer.theta.size
    return agreed(trial, lambda t: t.option, lambda t: t.theta[m:], scorer.score)
