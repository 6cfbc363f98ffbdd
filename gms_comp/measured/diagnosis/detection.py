"""What ``none`` rules out: each catalogue effect's smallest size this trace would reveal
(docs/diagnosis-method.md, section 7).

On the final model less that effect, at a few shapes of its grid: an effect of size s adds
s x to the force (x its column at unit size); the model without it, fitted to the force
with it, leaves what it cannot absorb of s x on the held-out rows, and the model with it
what it leaves now. The limit is the least s the criterion keeps (by prediction, or at its
events each left out, and by size), by bisection in log; for a filter, the smallest filter
of the model force it keeps. The limit stated is at the shape where it is the median.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.measured.diagnosis.candidates import Option, Scorer, acts_locally
from gms_comp.measured.diagnosis.config import DiagnosisConfig
from gms_comp.measured.diagnosis.criterion import lowers, lowers_locally
from gms_comp.measured.diagnosis.design import Columns, GramDesign, PartDesign, solve_gram
from gms_comp.measured.diagnosis.refit import Extended
from gms_comp.measured.policies import POLICIES, Policy
from gms_comp.runtime import effects as fx

# The size bracket: from the size floor, doubled at most this often to find a size kept.
DOUBLINGS = 40


@dataclass(frozen=True)
class Limit:
    """The just-detectable effect at the stated shape: its parameters and what they come
    to along the trace (``figures``); the figure the limit is told in
    (``Policy.limit_figure``) at the smallest and largest limit over the shapes tried."""

    figures: dict[str, float]
    span: dict[str, list[float]]


def detection_limits(
    extended: Extended, steps: Sequence[FloatArray], kind: str, level_N: float,
    presliding_m: float, noise_N: float, cfg: DiagnosisConfig,
) -> dict[str, Limit]:  # fmt: skip
    """Each catalogue effect's limit on the final design of ``extended`` less that effect,
    the baseline free to take up part of it along its level's and knots' ``steps``
    (:func:`.intervals.tangents`); ``kind``: the force kind (effects for it only)."""
    parts, chosen = extended.parts, extended.chosen
    out: dict[str, Limit] = {}
    models: dict[tuple[int, ...], tuple[Scorer, GramDesign]] = {}
    for name, rules in POLICIES.items():
        if kind not in rules.force_kinds:
            continue
        others = [o for o in chosen if o.effect is not rules.effect]
        key = tuple(id(o) for o in others)
        if key not in models:
            scorer = Scorer(parts, others, cfg.selection)
            models[key] = scorer, _free(scorer.designs, steps)
        scorer, free = models[key]
        shapes = rules.detection_shapes(parts[0].ctx, presliding_m, cfg.detection.shapes)
        found = [
            e
            for shape in shapes
            if (e := _limit(scorer, free, rules, shape, level_N, noise_N, cfg)) is not None
        ]
        if found:
            found.sort(key=rules.size)
            figures = [{**e.parameters(), **rules.in_context(e, parts[0].ctx)} for e in found]
            told = rules.limit_figure or rules.size_parameter
            span = sorted(float(f[told]) for f in figures if told in f)
            stated = (len(found) - 1) // 2
            out[name] = Limit(figures[stated], {told: [span[0], span[-1]]})
    return out


def _free(designs: Sequence[PartDesign], steps: Sequence[FloatArray]) -> GramDesign:
    """The designs with the baseline's steps (free coefficients) beside their columns."""
    return GramDesign([
        PartDesign(
            Columns(np.column_stack([d.columns.values, s]),
                    np.concatenate([d.columns.lower, np.full(s.shape[1], -np.inf)])),
            d.force_N, d.train, d.held,
        )
        for d, s in zip(designs, steps, strict=True)
    ])  # fmt: skip


def _limit(
    scorer: Scorer, free: GramDesign, rules: type[Policy], shape: dict[str, float],
    level_N: float, noise_N: float, cfg: DiagnosisConfig,
) -> fx.Effect | None:  # fmt: skip
    """The smallest effect of ``rules`` at ``shape`` the criterion keeps, or None
    (``free``: the design of ``scorer`` with the baseline's steps beside it)."""
    if issubclass(rules.effect, fx.FilterEffect):
        return _filter_limit(scorer, free, rules, shape, level_N, cfg)
    effect: fx.Effect | None = None
    for _ in range(2 if rules.set_by_size else 1):  # a shape set by the size: at the limit's
        opt = Option(rules.effect, shape)
        keep, unit = _additive(scorer, free, opt, level_N, noise_N, cfg)
        peak = float(np.max(np.abs(scorer.extra(opt)[0].values @ unit)))
        start = cfg.selection.min_effect_fraction * level_N / peak if peak > 0.0 else 1e-12
        size = _bisect(keep, start, cfg.detection.bisections)
        if size is None:
            return effect
        effect = rules.effect.from_coefficients(size * unit, shape)
        shape = rules.consistent_shape(size * unit, shape)
    return effect


def _additive(
    scorer: Scorer, free: GramDesign, opt: Option, level_N: float, noise_N: float,
    cfg: DiagnosisConfig,
) -> tuple[Callable[[float], bool], FloatArray]:  # fmt: skip
    """Whether the criterion keeps ``opt``'s effect added at a size (its first
    coefficient), and the unit coefficients (one size's)."""
    rules = cfg.selection
    trial = scorer.score(opt)
    extra = scorer.extra(opt)
    unit = np.zeros(extra[0].values.shape[1])
    unit[0] = 1.0
    x = [e.values @ unit for e in extra]
    gram = free
    pushed = gram.cross_products([c[:, None] for c in x])[0][:, 0]
    new = gram.trial(extra)[1]
    held_x = np.concatenate([c[fp.part.held] for c, fp in zip(x, scorer.parts, strict=True)])
    apart = scorer.told_apart(opt)
    local = acts_locally(trial, rules)
    events = None
    if local:
        spans = scorer.events(trial)
        base_y, new_y = gram.left_out(extra, spans, rules.left_out_folds)
        moved = GramDesign(
            [PartDesign(p.columns, c, p.train, p.held) for p, c in zip(gram.parts, x, strict=True)]
        )
        base_x = moved.left_out(extra, spans, rules.left_out_folds)[0]
        events = (base_y, base_x, new_y)
    peak = float(np.max(np.abs(x[0]))) if x[0].size else 0.0

    def keep(size: float) -> bool:
        theta = solve_gram(gram.gram, gram.rhs + size * pushed, gram.lower)
        base = gram.held_residual(theta) + size * held_x
        worth = lowers(rules, base, new)
        if not worth and events is not None:
            worth = lowers_locally(rules, events[0] + size * events[1], events[2], noise_N)
        if worth and apart is not None:
            worth = bool(np.any(apart)) and lowers(rules, base[apart], new[apart])
        effect = opt.effect.from_coefficients(size * unit, opt.shape)
        relative = opt.policy.relative_size(effect, scorer.parts[0].ctx)
        if relative is not None and relative < rules.min_effect_fraction:
            return False
        return worth and size * peak >= rules.min_effect_fraction * level_N

    return keep, unit


def _bisect(keep: Callable[[float], bool], start: float, halvings: int) -> float | None:
    """The least size ``keep`` holds for, from ``start`` (doubled until it holds, then the
    bracket halved ``halvings`` times in log); None if it never holds."""
    lo, hi = start, start
    if keep(start):
        return start
    for _ in range(DOUBLINGS):
        lo, hi = hi, 2.0 * hi
        if keep(hi):
            break
    else:
        return None
    for _ in range(halvings):
        mid = math.sqrt(lo * hi)
        lo, hi = (lo, mid) if keep(mid) else (mid, hi)
    return hi


def _filter_limit(
    scorer: Scorer, free: GramDesign, rules: type[Policy], shape: dict[str, float],
    level_N: float, cfg: DiagnosisConfig,
) -> fx.Effect | None:  # fmt: skip
    """The smallest (``Policy.size``) filter of the model force in its shape bounds that
    the criterion keeps, or None: its size key bisected in log between its bounds."""
    effect_cls = rules.effect
    assert issubclass(effect_cls, fx.FilterEffect)
    key = rules.size_parameter
    lo, hi = rules.shape_bounds(scorer.parts[0].ctx, 0.0)[key]
    gram = free
    now = gram.held_residual(gram.fit())
    models = [scorer.model(i) for i in range(len(scorer.parts))]

    def at(u: float) -> fx.FilterEffect:
        return effect_cls.from_shape({**shape, key: lo * (hi / lo) ** u})

    # u runs from the smallest filter to the largest
    grow = rules.size(at(1.0)) > rules.size(at(0.0))

    def keep(u: float) -> bool:
        filt = at(u if grow else 1.0 - u)
        d = [
            filt.filter_columns(m, fp.ctx.sample_time_s) - m
            for m, fp in zip(models, scorer.parts, strict=True)
        ]
        pushed = gram.cross_products([c[:, None] for c in d])[0][:, 0]
        theta = solve_gram(gram.gram, gram.rhs + pushed, gram.lower)
        held_d = np.concatenate([c[fp.part.held] for c, fp in zip(d, scorer.parts, strict=True)])
        base = gram.held_residual(theta) + held_d
        big = float(np.max(np.abs(d[0]))) >= cfg.selection.min_effect_fraction * level_N
        return big and lowers(cfg.selection, base, now)

    if not keep(1.0):
        return None
    small, large = 0.0, 1.0
    for _ in range(cfg.detection.bisections):
        mid = 0.5 * (small + large)
        small, large = (small, mid) if keep(mid) else (mid, large)
    return at(large if grow else 1.0 - large)
