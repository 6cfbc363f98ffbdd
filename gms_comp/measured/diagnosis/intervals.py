"""How sure: a 95 % interval for every parameter of every kept effect
(docs/diagnosis-method.md, section 6).

The final model linearised about its fit: its design columns and, for each nonlinear
parameter (a free baseline's C_v and v_t, every kept shape in log), the model's change per
step. A delete-a-group jackknife over ``jackknife_blocks`` contiguous blocks of the
training rows gives each parameter's spread (the noise, its correlation in time, the
trades between parameters, the misfit where it changes along the trace); each interval
is at least ``model_form_share`` of the parameter's size (the misfit a fit absorbs into its
parameters never shows in its residual). Clipped at a shape's search bounds and at the
coefficients' physical bound; reaching either is said (``at_bound``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

from gms_comp.arrays import FloatArray
from gms_comp.measured.diagnosis.baseline import FittedPart, rebased, refit_gms_force
from gms_comp.measured.diagnosis.basis import FreeBasis
from gms_comp.measured.diagnosis.candidates import Option, design, through, widths
from gms_comp.measured.diagnosis.config import DiagnosisConfig
from gms_comp.measured.diagnosis.design import Columns, GramDesign, PartDesign
from gms_comp.measured.diagnosis.refit import Extended
from gms_comp.runtime import effects as fx

# Steps of the linearisation: C_v by LEVEL_STEP, v_t and every shape by a factor e^LOG_STEP.
LEVEL_STEP = 0.01
LOG_STEP = 0.02
# A shape's interval spans at most e^+-MAX_LOG_WIDTH (then its search bounds clip it).
MAX_LOG_WIDTH = 50.0


@dataclass(frozen=True)
class Intervals:
    """One kept effect's intervals (``bounds``: name -> (low, high)) and the names whose
    interval reaches the bound of its search or of its physical range."""

    bounds: dict[str, tuple[float, float]]
    at_bound: tuple[str, ...]

    def to_json(self) -> dict[str, list[float]]:
        """``{name: [low, high]}``."""
        return {k: [float(lo), float(hi)] for k, (lo, hi) in self.bounds.items()}


Column = tuple[int | None, str, list[FloatArray]]  # owner (a chosen index), key, per part


def intervals(
    extended: Extended, steps: Sequence[FloatArray], cfg: DiagnosisConfig
) -> tuple[Intervals, ...]:
    """The intervals of each kept effect of ``extended`` (ranked order); ``steps``: the
    baseline's (:func:`tangents`)."""
    parts, chosen, theta = extended.parts, list(extended.chosen), extended.theta
    if not chosen:
        return ()
    designs = design(parts, chosen)
    model = [d.columns.values @ theta for d in designs]
    level: list[Column] = [
        (None, "level", [s[:, j] for s in steps]) for j in range(steps[0].shape[1])
    ]
    moved = level + _shape_columns(parts, chosen, theta, model)
    gram = GramDesign([
        PartDesign(
            Columns(np.column_stack([d.columns.values, *(c[2][i] for c in moved)]),
                    np.concatenate([d.columns.lower, np.full(len(moved), -np.inf)])),
            d.force_N, d.train, d.held,
        )
        for i, d in enumerate(designs)
    ])  # fmt: skip
    rules = cfg.intervals
    replicates = np.array(gram.jackknife(rules.jackknife_blocks))
    groups = replicates.shape[0]
    t = float(stats.t.ppf(0.5 + rules.level / 2, groups - 1))
    out = []
    start = parts[0].base.values.shape[1]
    fitted = np.concatenate([theta, np.zeros(len(moved))])
    for k, (opt, width) in enumerate(zip(chosen, widths(parts, chosen), strict=True)):
        start += width
        keys = [(theta.size + j, c[1]) for j, c in enumerate(moved) if c[0] == k]
        named = _reader(opt, slice(start - width, start), keys, parts[0].ctx)
        centre = named(fitted)
        spread = _jackknife(named, replicates, centre)
        share = rules.model_form_share
        presliding = extended.baseline.presliding_m
        found = _bounded(opt, width, centre, spread, t, share, presliding, parts)
        ridge = opt.policy.ridge(centre, found.bounds, parts[0].ctx, presliding)
        bounds = {k: _union(v, ridge[k]) if k in ridge else v for k, v in found.bounds.items()}
        out.append(Intervals(bounds, tuple(dict.fromkeys([*found.at_bound, *ridge]))))
    return tuple(out)


def tangents(extended: Extended) -> list[FloatArray]:
    """Each part's columns of the model's change per step of the free baseline's level
    and knots (:func:`_level_columns`), one (rows, k) array per part (k may be 0): the
    directions the baseline can move in to take up what an effect would add."""
    model = [d.columns.values @ extended.theta for d in design(extended.parts, extended.chosen)]
    moved = _level_columns(extended, model)
    return [
        np.column_stack([c[2][i] for c in moved]) if moved else np.zeros((m.size, 0))
        for i, m in enumerate(model)
    ]


def _level_columns(extended: Extended, model: Sequence[FloatArray]) -> list[Column]:
    """The model's change per step of the free baseline's C_v and (in log) v_t, the GMS
    force the effects scale moved with it; none for a table's baseline."""
    basis = extended.basis
    if not isinstance(basis, FreeBasis):
        return []
    out: list[Column] = []
    cv = basis.slip_level + LEVEL_STEP
    steps = (
        ("slip_level", LEVEL_STEP, dataclasses.replace(basis, slip_level=cv)),
        ("transition_velocity_m_s", LOG_STEP, dataclasses.replace(
            basis, transition_velocity_m_s=basis.transition_velocity_m_s * math.exp(LOG_STEP))),
    )  # fmt: skip
    for key, step, level in steps:
        parts = refit_gms_force(rebased(extended.baseline, level), extended.theta, level)
        changed = [d.columns.values @ extended.theta for d in design(parts, extended.chosen)]
        out.append((None, key, [(a - b) / step for a, b in zip(changed, model, strict=True)]))
    return out + _knot_columns(extended)


def _knot_columns(extended: Extended) -> list[Column]:
    """The model's change per step (in log) of each kept element's break-away: the
    elements' shape trades with the effects at the reversals (a filter's lag, a
    transient), all of them stepped in one pass of the GMS kernel."""
    basis = extended.basis
    assert isinstance(basis, FreeBasis)
    limits = extended.theta[: basis.breakaway_m.size]
    active = np.flatnonzero(limits > 0.0)
    if active.size == 0:
        return []
    moved = dataclasses.replace(basis, breakaway_m=basis.breakaway_m[active] * math.exp(LOG_STEP))
    filters = [o for o in extended.chosen if o.is_filter]
    columns = []
    for fp in extended.parts:
        dt = fp.ctx.sample_time_s
        change = (moved.columns(fp.part.kin) - fp.phi[:, active]) * limits[active] / LOG_STEP
        columns.append(through(filters, change, dt))
    return [(None, f"breakaway_{i}", [c[:, j] for c in columns]) for j, i in enumerate(active)]


def _shape_columns(
    parts: Sequence[FittedPart], chosen: list[Option], theta: FloatArray,
    model: Sequence[FloatArray],
) -> list[Column]:  # fmt: skip
    """The model's change per step (in log) of each kept effect's continuous shape keys."""
    out: list[Column] = []
    for k, opt in enumerate(chosen):
        for key in continuous(opt):
            other = opt.with_value(key, opt.shape[key] * math.exp(LOG_STEP))
            swapped = [other if o is opt else o for o in chosen]
            changed = [d.columns.values @ theta for d in design(parts, swapped)]
            out.append((k, key, [(a - b) / LOG_STEP for a, b in zip(changed, model, strict=True)]))
    return out


def continuous(opt: Option) -> list[str]:
    """The shape keys of ``opt`` that are neither set by its size nor discrete."""
    rules = opt.policy
    return [k for k in opt.shape if k not in (*rules.set_by_size, *rules.discrete)]


Reader = Callable[[FloatArray], dict[str, float]]


def _reader(
    opt: Option, coefficients: slice, keys: Sequence[tuple[int, str]], ctx: fx.Context
) -> Reader:
    """The named parameters (and in-context figures) of ``opt``'s effect at a vector of
    the linearised system: its coefficients, its shape moved by the log steps at ``keys``."""

    def named(vector: FloatArray) -> dict[str, float]:
        shape = dict(opt.shape)
        for j, key in keys:
            shape[key] = opt.shape[key] * math.exp(float(vector[j]))
        if issubclass(opt.effect, fx.FilterEffect):
            effect: fx.Effect = opt.effect.from_shape(shape)
        else:
            effect = opt.effect.from_coefficients(vector[coefficients], shape)
        values = {**effect.parameters(), **opt.policy.in_context(effect, ctx)}
        return {k: v for k, v in values.items() if k not in _fixed(opt)}

    return named


def _fixed(opt: Option) -> tuple[str, ...]:
    """The parameters no interval is given for (set by the size, discrete)."""
    return (*opt.policy.set_by_size, *opt.policy.discrete)


def _jackknife(named: Reader, replicates: FloatArray, centre: dict[str, float]) -> dict[str, float]:
    """Each parameter's jackknife standard error (a phase's replicates on the same turn)."""
    values = [named(r) for r in replicates]
    groups = len(values)
    out = {}
    for name, value in centre.items():
        v = np.array([x[name] for x in values])
        if name.endswith("_rad"):
            v = value + np.angle(np.exp(1j * (v - value)))
        out[name] = math.sqrt((groups - 1) / groups * float(np.sum((v - v.mean()) ** 2)))
    return out


def _bounded(
    opt: Option, width: int, centre: dict[str, float], spread: dict[str, float], t: float,
    share: float, presliding_m: float, parts: Sequence[FittedPart],
) -> Intervals:  # fmt: skip
    """The intervals ``centre +- t spread``, at least ``share`` of each
    parameter's size (a shape's in log; a coefficient's from its value at no effect):
    the model's form, which no fit of it sees; clipped at a shape's search bounds and at
    the coefficients' physical bound."""
    rules = opt.policy
    bounds = rules.shape_bounds(parts[0].ctx, presliding_m)
    floors = _floors(opt, width)
    nothing = {} if opt.is_filter else _named_at(opt, np.zeros(width), parts[0].ctx)
    found: dict[str, tuple[float, float]] = {}
    at: list[str] = []
    for name, value in centre.items():
        half = t * spread[name]
        if half <= 0.0:  # a figure of the trace alone (its median standstill)
            continue
        if name in opt.shape:  # in log, far past any search bound at the most
            relative = min(max(half / max(abs(value), 1e-300), share), MAX_LOG_WIDTH)
            lo, hi = value * math.exp(-relative), value * math.exp(relative)
            lo_b, hi_b = bounds.get(name, (0.0, math.inf))
            if lo <= lo_b or hi >= hi_b:
                at.append(name)
            found[name] = (max(lo, lo_b), min(hi, hi_b))
            continue
        if not name.endswith("_rad"):  # an angle has no size
            half = max(half, share * abs(value - nothing.get(name, 0.0)))
        lo, hi = value - half, value + half
        floor = floors.get(name)
        if floor is not None and lo <= floor:
            at.append(name)
            lo = floor
        found[name] = (lo, hi)
    return Intervals(found, tuple(at))


def _union(a: tuple[float, float], b: tuple[float, float]) -> tuple[float, float]:
    return min(a[0], b[0]), max(a[1], b[1])


def _named_at(opt: Option, coefficients: FloatArray, ctx: fx.Context) -> dict[str, float]:
    """The parameters and in-context figures of ``opt``'s effect at ``coefficients``."""
    effect = opt.effect.from_coefficients(coefficients, opt.shape)
    return {**effect.parameters(), **opt.policy.in_context(effect, ctx)}


def _floors(opt: Option, width: int) -> dict[str, float]:
    """The lowest value each coefficient-given parameter can take (``width``: how many
    coefficients): at the coefficients' physical bound; a magnitude (it reads alike at
    negated coefficients) at zero."""
    if opt.is_filter:
        return {}
    rules = opt.policy
    ones = np.ones(width)
    plus = opt.effect.from_coefficients(ones, opt.shape).parameters()
    minus = opt.effect.from_coefficients(-ones, opt.shape).parameters()
    floors = {k: 0.0 for k, v in plus.items() if k not in opt.shape and v == minus[k] and v > 0}
    if math.isfinite(rules.coefficient_lower):
        lowest = opt.effect.from_coefficients(np.full(width, rules.coefficient_lower), opt.shape)
        floors |= {k: v for k, v in lowest.parameters().items() if k not in opt.shape}
    return floors
