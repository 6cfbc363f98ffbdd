"""Stage 5: the kept effects refitted jointly, the backward pass, and the extended model run
as the compensator runs it.

The effects that scale the friction are columns of the GMS force: it is updated to the
joint fit and the fit repeated (``JOINT_REFITS`` times), every additive effect's shape
searched again by training RMS each time. The free baseline is placed again on the force
less the effects its elements took part of (``Policy.elements_take_part``) and fitted
through a kept filter (:mod:`.sensed`); the slip level is searched with the one shape that
trades against it (:mod:`.level`). Backward pass: an effect no longer worth keeping on the
joint design is dropped, one the joint fit leaves under the size floor too, and an effect
that trades with the level is judged against the model refitted without it.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.gms import GmsParams
from gms_comp.measured.diagnosis.baseline import (
    Baseline,
    Basis,
    FittedPart,
    fit_baseline,
    fitted_through,
    held_residual,
    placed_on,
    rebased,
    refit_gms_force,
)
from gms_comp.measured.diagnosis.basis import FreeBasis
from gms_comp.measured.diagnosis.candidates import (
    Option,
    Scorer,
    base_gram,
    design,
    fit_on,
    through,
    widths,
)
from gms_comp.measured.diagnosis.config import DiagnosisConfig, SelectionConfig
from gms_comp.measured.diagnosis.criterion import admissible, agreed, lowers
from gms_comp.measured.diagnosis.design import GramDesign, every_row, rms
from gms_comp.measured.diagnosis.level import (
    extended_force,
    extended_model,
    level_with_shape,
    refine_slip_level,
)
from gms_comp.measured.diagnosis.selection import Selection, local_search
from gms_comp.measured.policies import Leftover
from gms_comp.runtime import effects as fx

JOINT_REFITS = 3


@dataclass(frozen=True)
class Ranked:
    """A kept effect with the held-out RMS once it was added."""

    effect: fx.Effect
    heldout_rms_N: float


@dataclass(frozen=True)
class Extended:
    """The output of :func:`refit`."""

    baseline: Baseline
    ranked: tuple[Ranked, ...]
    gms: GmsParams
    extensions: tuple[fx.Effect, ...]
    predictions: tuple[FloatArray, ...]
    heldout_rms_N: float
    held_residual_N: FloatArray
    # the free baseline re-placed on the force less the kept effects the elements took part
    # of, if fitted
    placed: Baseline | None = None
    # the final design: its parts (the GMS force the effects scale), the kept options in
    # the ranked order, and the coefficients fitted on the training rows
    parts: tuple[FittedPart, ...] = ()
    chosen: tuple[Option, ...] = ()
    theta: FloatArray = field(default_factory=lambda: np.zeros(0))
    basis: Basis | None = None


def refit(selection: Selection, cfg: DiagnosisConfig) -> Extended:
    """:func:`refit_kept`, then the backward pass for the effects that trade against the
    slip level (``Policy.level_shape``, ``free_level``): each such effect kept beside
    another, or kept with the level free, the last kept first, stays only if the model
    with it beats, by the criterion, the model refitted without it from the level the
    selection started from, whose level is searched as far as the one with it (on both
    tails, from a grid): the level, searched further than the selection's grid, may carry
    what the effect carried (a Stribeck fall kept at a grid's level beside a drift; a
    drift beside a reversal transient, standing in for the level's rise). The others
    were judged on the joint design already (:func:`refit_kept`'s backward pass)."""
    extended = refit_kept(selection, cfg)
    for opt in reversed(selection.chosen):
        if opt not in selection.chosen or not _judged(selection, opt):
            continue
        start = selection.level_from or selection.baseline
        rest = [
            (o, h) for o, h in zip(selection.chosen, selection.heldout_rms_N, strict=True)
            if o is not opt
        ]  # fmt: skip
        # from the same baseline, the elements re-placed for the first refit serve this one
        placed = extended.placed if start is selection.baseline else None
        fewer = Selection(
            start, tuple(o for o, _ in rest), tuple(h for _, h in rest), selection.last_round
        )
        without = refit_kept(fewer, cfg, placed, alone=True)
        if not lowers(cfg.selection, without.held_residual_N, extended.held_residual_N):
            selection, extended = fewer, without
    return extended


def _judged(selection: Selection, opt: Option) -> bool:
    """Whether :func:`refit` judges ``opt`` against the model without it: its policy
    scores it with the level free (``free_level``) and it was kept so or beside another
    effect, or its shape trades with the level (``level_shape``) and it was kept beside
    another."""
    rules, beside = opt.policy, len(selection.chosen) > 1
    free = rules.free_level and (selection.level_from is not None or beside)
    return free or (rules.level_shape is not None and beside)


def refit_kept(
    selection: Selection, cfg: DiagnosisConfig, placed: Baseline | None = None,
    alone: bool = False,
) -> Extended:  # fmt: skip
    """All coefficients fitted jointly with every kept effect present, the backward pass on
    the joint design (:func:`_prune`), the extended model (GMS kernel, then the effects)
    simulated along every part."""
    chosen = list(selection.chosen)
    history = list(selection.heldout_rms_N)
    start, placed = _placed_again(selection.baseline, chosen, cfg, placed)
    baseline = sensed_again(start, chosen, cfg.selection)
    parts = baseline.parts
    basis = baseline.basis
    if chosen:
        slip = refine_slip_level(baseline, lambda p: _train_rms(p, chosen))
        if slip is not None:
            basis, parts = slip, rebased(baseline, slip)
        chosen, history = _prune(
            parts, chosen, history, cfg, baseline.sliding_force_N, baseline.prepared.noise_N
        )
    theta = GramDesign(design(parts, chosen)).fit()
    parts, chosen, theta = _joint_refits(parts, basis, chosen, theta, baseline.presliding_m)
    basis, parts, chosen, theta = _with_level(baseline, basis, parts, chosen, theta, alone)
    forces = _added_forces(parts, chosen, theta)
    kept = _floored(chosen, forces, cfg.selection.min_effect_fraction * baseline.sliding_force_N)
    if len(kept) < len(chosen):
        history = [h for o, h in zip(chosen, history, strict=True) if o in kept]
        chosen = kept
        theta = GramDesign(design(parts, chosen)).fit()
        # what a dropped effect carried goes back to the level it was searched with
        basis, parts, chosen, theta = _with_level(baseline, basis, parts, chosen, theta, alone)
        forces = _added_forces(parts, chosen, theta)
    if len(chosen) > 1:
        order, history = _rank(parts, chosen, forces, cfg.selection)
        if order != chosen:
            chosen = order
            theta = GramDesign(design(parts, chosen)).fit()
    gms, extensions = extended_model(baseline, basis, parts, chosen, theta)
    ranked = tuple(Ranked(e, h) for e, h in zip(extensions[: len(chosen)], history, strict=True))
    predictions = tuple(extended_force(fp, gms, extensions) for fp in parts)
    held = held_residual(parts, predictions)
    return Extended(
        baseline, ranked, gms, tuple(extensions), predictions, rms(held), held, placed, parts,
        tuple(chosen), theta, basis,
    )  # fmt: skip


def _with_level(
    baseline: Baseline, basis: Basis, parts: tuple[FittedPart, ...], chosen: list[Option],
    theta: FloatArray, alone: bool = False,
) -> tuple[Basis, tuple[FittedPart, ...], list[Option], FloatArray]:  # fmt: skip
    """The slip level searched with the shape it trades against (:mod:`.level_search`)
    and everything refitted on it (:func:`_joint_refits`), if the search found a better
    level; else the arguments as given."""
    joint = level_with_shape(baseline, basis, chosen, JOINT_REFITS, alone)
    if joint is None:
        return basis, parts, chosen, theta
    basis, chosen = joint
    parts = rebased(baseline, basis)
    theta = GramDesign(design(parts, chosen)).fit()
    parts, chosen, theta = _joint_refits(parts, basis, chosen, theta, baseline.presliding_m)
    return basis, parts, chosen, theta


def _joint_refits(
    parts: tuple[FittedPart, ...], basis: Basis, chosen: list[Option], theta: FloatArray,
    presliding_m: float,
) -> tuple[tuple[FittedPart, ...], list[Option], FloatArray]:  # fmt: skip
    """``JOINT_REFITS`` times: the GMS force updated to the joint fit ``theta``, the
    additive effects' shapes searched again, everything fitted again."""
    # the GMS columns stay (their force is refitted), and so do the filters
    base = base_gram(parts, chosen)
    for _ in range(JOINT_REFITS if chosen else 0):
        parts = refit_gms_force(parts, theta, basis)
        chosen = _refine_shapes(parts, chosen, presliding_m)
        theta = fit_on(base, parts, chosen)[0]
    return parts, chosen, theta


def _placed_again(
    baseline: Baseline, chosen: list[Option], cfg: DiagnosisConfig, placed: Baseline | None
) -> tuple[Baseline, Baseline | None]:
    """The free baseline fitted again on the force less the fitted forces of the kept
    effects the blind elements took part of (``Policy.elements_take_part``: its elements,
    knots and slip level), if the kept effects then fit the held-out rows better, else
    ``baseline``; and the one fitted again. ``placed``: one already fitted again on
    ``baseline`` (by the refit with one effect more), used instead of a new fit."""
    again = any(o.policy.elements_take_part for o in chosen)
    if not again or not isinstance(baseline.basis, FreeBasis):
        return baseline, None
    before = Scorer(baseline.parts, chosen, cfg.selection)
    if placed is not None:
        better = Scorer(placed.parts, chosen, cfg.selection).heldout_rms_N < before.heldout_rms_N
        return (placed if better else baseline), placed
    filters = [o for o in chosen if o.is_filter]
    less = []
    for fp in baseline.parts:
        force = np.zeros(fp.part.force_N.size)
        at = fp.base.values.shape[1]
        for opt in (o for o in chosen if not o.is_filter):
            cols = opt.columns(fp, filters).values
            if opt.policy.elements_take_part:
                force += cols @ before.theta[at : at + cols.shape[1]]
            at += cols.shape[1]
        less.append(dataclasses.replace(fp.part, force_N=fp.part.force_N - force))
    prepared = dataclasses.replace(baseline.prepared, parts=tuple(less))
    trial = placed_on(baseline.prepared, fit_baseline(prepared, cfg, None))
    if Scorer(trial.parts, chosen, cfg.selection).heldout_rms_N < before.heldout_rms_N:
        return trial, trial
    return baseline, trial


def _prune(
    parts: Sequence[FittedPart], chosen: list[Option], history: list[float],
    cfg: DiagnosisConfig, level_N: float, noise_N: float,
) -> tuple[list[Option], list[float]]:  # fmt: skip
    """The backward pass on the joint design: each kept effect (the last first) dropped if
    it is no longer worth keeping on top of the others (it stood in for a slip level the
    blind baseline had not found, or for an effect kept after it)."""
    if len(chosen) < 2:
        return chosen, history
    kept = list(chosen)
    for opt in list(reversed(chosen)):
        others = [o for o in kept if o is not opt]
        if not others:
            continue
        trial = Scorer(parts, others, cfg.selection)
        if not admissible(cfg, trial, trial.score(opt), level_N, noise_N):
            kept = others
    return kept, [h for o, h in zip(chosen, history, strict=True) if o in kept]


def _added_forces(
    parts: Sequence[FittedPart], chosen: list[Option], theta: FloatArray
) -> list[FloatArray]:
    """What each of ``chosen`` adds to the jointly fitted model along the main part: an
    additive effect's own columns times its coefficients; a filter's, the model less the
    same coefficients unfiltered."""
    if not chosen:
        return []
    values = design(parts, chosen)[0].columns.values
    full = values @ theta
    added = []
    start = parts[0].base.values.shape[1]
    for opt, width in zip(chosen, widths(parts, chosen), strict=True):
        if opt.is_filter:
            rest = [o for o in chosen if o is not opt]
            added.append(full - design(parts, rest)[0].columns.values @ theta)
        else:
            added.append(values[:, start : start + width] @ theta[start : start + width])
        start += width
    return added


def _floored(chosen: list[Option], forces: list[FloatArray], floor_N: float) -> list[Option]:
    """The kept effects whose jointly fitted force (``forces``, :func:`_added_forces`)
    reaches ``floor_N`` somewhere (the selection's floor, ``min_effect_fraction`` of the
    sliding force): an effect kept on the baseline's force may be carried by the others
    once all are fitted together, and its fitted size go to its bound."""
    return [o for o, f in zip(chosen, forces, strict=True) if float(np.max(np.abs(f))) >= floor_N]


def _rank(
    parts: Sequence[FittedPart], chosen: list[Option], forces: list[FloatArray],
    rules: SelectionConfig,
) -> tuple[list[Option], list[float]]:  # fmt: skip
    """The kept effects, the largest force first (the RMS of what each adds to the jointly
    fitted model, ``forces``), each with the held-out RMS once it is added in that order."""
    size = {id(o): rms(f) for o, f in zip(chosen, forces, strict=True)}
    ranked = sorted(chosen, key=lambda o: size[id(o)], reverse=True)
    held = [Scorer(parts, ranked[: i + 1], rules).heldout_rms_N for i in range(len(ranked))]
    return ranked, held


def _train_rms(parts: Sequence[FittedPart], chosen: Sequence[Option]) -> float:
    gram = GramDesign(design(parts, chosen))
    return gram.train_rms(gram.fit())


def _refine_shapes(
    parts: Sequence[FittedPart], chosen: list[Option], presliding_m: float
) -> list[Option]:
    """The shapes of the additive effects searched by training RMS, each trial first made to
    agree with its fitted size (a dwell's ``reach`` with its gain): searched freely, the
    gain and the time constant trade along a ridge the coordinate steps cannot follow,
    and the shape moves off the gain its windows are computed at."""
    out = list(chosen)
    for i, opt in enumerate(chosen):
        if not opt.is_filter and opt.effect.SHAPE:
            out[i] = _refine_shape(parts, [*out[:i], *out[i + 1 :]], opt, presliding_m)
    return out


def _refine_shape(
    parts: Sequence[FittedPart], others: list[Option], opt: Option, presliding_m: float
) -> Option:
    """``opt``'s shape searched with the ``others`` fixed (see :func:`_refine_shapes`)."""
    designs = design(parts, others)
    rest = GramDesign(designs)  # the trials add their columns to it
    # an effect at few events is costed on every row; its size (which its shape must
    # agree with) is still the training rows' fit, as the model's coefficients are
    whole = GramDesign(every_row(designs)) if opt.policy.at_events else rest
    filters = [o for o in others if o.is_filter]
    m = rest.lower.size

    def fit(trial: Option) -> tuple[Option, FloatArray, float]:
        extra = [trial.columns(fp, filters) for fp in parts]
        theta, cost = rest.trial_train_rms(extra)
        return trial, theta, (cost if whole is rest else whole.trial_train_rms(extra)[1])

    def settled(trial: Option) -> tuple[Option, FloatArray, float]:
        return agreed(fit(trial), lambda f: f[0], lambda f: f[1][m:], fit)

    first, _, first_cost = settled(opt)
    rules = opt.policy
    if rules.at_events:  # from the best of its grid's time constants
        fixed = {k: opt.shape[k] for k in (*rules.set_by_size, *rules.discrete) if k in opt.shape}
        grid = {
            tuple(v for k, v in sorted(shape.items()) if k not in fixed): {**shape, **fixed}
            for shape in rules.shape_grid(parts[0].ctx, Leftover.empty(), presliding_m)
        }
        for shape in grid.values():
            trial, _, cost = settled(Option(opt.effect, shape))
            if cost < first_cost:
                first, first_cost = trial, cost
    bounds = rules.shape_bounds(parts[0].ctx, presliding_m)
    steps = rules.shape_steps(parts[0].ctx)
    best = local_search(
        first, lambda t: settled(t)[2], first_cost, bounds, rules.set_by_size, steps
    )
    return settled(best[0])[0]


def sensed_again(baseline: Baseline, chosen: list[Option], rules: SelectionConfig) -> Baseline:
    """``baseline`` with its elements fitted again through ``chosen``'s filters
    (:func:`~.baseline.fitted_through`) if ``chosen`` then fits the held-out rows better;
    else ``baseline`` (also without a filter kept, or with a table baseline)."""
    filters = [o for o in chosen if o.is_filter]
    if not filters or not isinstance(baseline.basis, FreeBasis):
        return baseline
    sensed = functools.partial(through, filters)
    trial = fitted_through(baseline, sensed, [o.effect.name for o in filters])
    if (
        Scorer(trial.parts, chosen, rules).heldout_rms_N
        < Scorer(baseline.parts, chosen, rules).heldout_rms_N
    ):
        return trial
    return baseline
