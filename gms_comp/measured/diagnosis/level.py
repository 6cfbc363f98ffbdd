"""The slip level searched with the effects (:mod:`.slip_level` is the level and its steps).

- In the selection's first rounds, an effect whose policy says so (``free_level``: a
  Stribeck fall, which drags the blind GMS's level down) is also scored on baselines
  refitted on a grid of levels above the baseline's (:func:`with_free_level`).
- In the refit, the level is stepped again with the kept effects present
  (:func:`refine_slip_level`), then searched together with the one shape that trades
  against it (``Policy.level_shape``) by a bounded Nelder-Mead from the best of a small
  grid, on each of the level's tails, the tail taken by the held-out RMS of the extended
  model as the compensator runs it (:func:`level_with_shape`).
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from gms_comp.arrays import FloatArray
from gms_comp.gms import GmsParams, scaled, simulate
from gms_comp.measured.diagnosis.baseline import (
    Baseline,
    Basis,
    FittedPart,
    drive_mass,
    fitted_on,
    held_residual,
    rebased,
    rebased_gram,
    refit_gms_force,
)
from gms_comp.measured.diagnosis.basis import FreeBasis, TableBasis
from gms_comp.measured.diagnosis.candidates import (
    Option,
    Scorer,
    Trial,
    base_gram,
    effect_of,
    fit_on,
    options,
    widths,
)
from gms_comp.measured.diagnosis.design import rms
from gms_comp.measured.diagnosis.slip_level import (
    REFINE_STEPS,
    REFIT_TAILS,
    SLIP_LEVEL_RANGE,
    Level,
    coordinate_steps,
    level_of,
    transition_range,
)
from gms_comp.runtime import effects as fx

# The free-level grid: C_v above the baseline's by these steps (a fall drags the level
# down), FREE_TRANSITIONS transition velocities over the baseline's range, then at the
# best level the transition halfway (in log) to the grid's points either side.
FREE_LEVEL_STEPS = (0.05, 0.1, 0.15, 0.2, 0.3)
FREE_TRANSITIONS = 3
# The joint search: first steps of the simplex in (C_v, ln v_t, ln shape), at most
# JOINT_LEVEL_EVALS trials, from the best of a grid of +- JOINT_GRID_STEPS around its start.
JOINT_LEVEL_STEPS = (0.05, float(np.log(2.0)), float(np.log(1.3)))
JOINT_LEVEL_EVALS = 60
JOINT_GRID_STEPS = (0.05, float(np.log(1.6)), float(np.log(1.5)))


@dataclass(frozen=True)
class FreeLevel:
    """The baseline refitted at another slip level, and Stribeck's best trial on it;
    ``plain``: the design without Stribeck at the grid's level where it fits best."""

    baseline: Baseline
    scorer: Scorer
    trial: Trial
    plain: Scorer


def with_free_level(
    effect: type[fx.Effect], baseline: Baseline, now: Scorer,
    fitted: dict[tuple[float, float], Baseline] | None = None,
) -> FreeLevel | None:  # fmt: skip
    """``effect``'s best trial (held-out RMS) on top of the options ``now`` holds, over the
    grid of slip levels; None for a table's baseline, or where ``now`` leaves less than
    ``free_level_ratio`` x the noise held out. ``fitted``: the baselines fitted so far on
    the grid's levels, by (C_v, v_t), kept across the selection's rounds."""
    basis = baseline.basis
    if not isinstance(basis, FreeBasis):
        return None
    ratio = now.rules.free_level_ratio
    if now.heldout_rms_N < ratio * baseline.prepared.noise_N:
        return None
    chosen = now.chosen
    fitted = {} if fitted is None else fitted
    vmax = max(float(np.max(np.abs(p.kin.velocity_m_s))) for p in baseline.prepared.parts)
    best: FreeLevel | None = None
    plain: Scorer | None = None
    best_at = (basis.slip_level, basis.transition_velocity_m_s)

    def score(cv: float, vt: float) -> None:
        nonlocal best, plain, best_at
        key = (cv, vt)
        if key not in fitted:
            level = dataclasses.replace(basis, slip_level=cv, transition_velocity_m_s=vt)
            fitted[key] = fitted_on(baseline.prepared, level, baseline.info)
        rebased = fitted[key]
        scorer = Scorer(rebased.parts, chosen, now.rules)
        if chosen:
            # the GMS force that Stribeck scales, fitted beside the effects kept
            parts = refit_gms_force(rebased.parts, scorer.theta, rebased.basis)
            rebased = dataclasses.replace(rebased, parts=parts)
            scorer = Scorer(parts, chosen, now.rules)
        if plain is None or scorer.heldout_rms_N < plain.heldout_rms_N:
            plain = scorer
        grid = options(effect, scorer, rebased.presliding_m)
        trial = min(scorer.score_all(grid), key=lambda t: t.heldout_rms_N)
        if best is None or trial.heldout_rms_N < best.trial.heldout_rms_N:
            best, best_at = FreeLevel(rebased, scorer, trial, scorer), key

    transitions = np.geomspace(*transition_range(vmax), FREE_TRANSITIONS)
    for step in FREE_LEVEL_STEPS:
        for vt in transitions:
            score(min(basis.slip_level + step, SLIP_LEVEL_RANGE[1]), float(vt))
    if best is None or plain is None:
        return None
    # the best level's transition velocity halfway (in log) to the grid's either side
    cv, at = best_at
    half = math.sqrt(float(transitions[1] / transitions[0]))
    for vt in (at / half, at * half):
        if transitions[0] < vt < transitions[-1]:
            score(cv, vt)
    return dataclasses.replace(best, plain=plain)


def level_with_shape(
    baseline: Baseline, basis: Basis, chosen: list[Option], refits: int, alone: bool = False
) -> tuple[FreeBasis, list[Option]] | None:
    """A kept effect's level shape (:func:`level_traded`) searched with the free basis's
    C_v and v_t on each of the level's tails, each trial costed by the training RMS once
    the GMS force is updated ``refits`` times; of the tails' best points that train better
    than the start, the one that holds out best; None when no such effect is kept (unless
    ``alone``: the level alone), the basis is a table's, or nothing better was found."""
    at = level_traded(chosen)
    if (at is None and not alone) or not isinstance(basis, FreeBasis):
        return None
    vmax = max(float(np.max(np.abs(p.kin.velocity_m_s))) for p in baseline.prepared.parts)
    ranges = [transition_range(vmax, np.inf)]
    key = ""
    if at is not None:
        rules = chosen[at].policy
        key = str(rules.level_shape)
        ranges.append(rules.shape_bounds(baseline.parts[0].ctx, baseline.presliding_m)[key])
    bounds = [SLIP_LEVEL_RANGE, *((float(np.log(lo)), float(np.log(hi))) for lo, hi in ranges)]
    dims = len(bounds)

    def unpack(u: FloatArray, tail: float) -> tuple[FreeBasis, list[Option]]:
        level = dataclasses.replace(
            basis, slip_level=float(u[0]), transition_velocity_m_s=float(np.exp(u[1])),
            transition_tail=tail,
        )  # fmt: skip
        if at is None:
            return level, list(chosen)
        traded = chosen[at].with_value(key, float(np.exp(u[2])))
        return level, [*chosen[:at], traded, *chosen[at + 1 :]]

    def fitted(
        u: FloatArray, tail: float
    ) -> tuple[tuple[FittedPart, ...], list[Option], FloatArray, float]:
        level, options = unpack(u, tail)
        parts, gram = rebased_gram(baseline, level)
        # without a filter the base columns' Gram matrix is the one the rebase fitted
        base = base_gram(parts, options) if any(o.is_filter for o in options) else gram
        theta, train_rms = fit_on(base, parts, options)
        for _ in range(refits):
            parts = refit_gms_force(parts, theta, level)
            theta, train_rms = fit_on(base, parts, options)
        return parts, options, theta, train_rms

    def cost(u: FloatArray, tail: float) -> float:
        return fitted(u, tail)[3]

    def held_out(u: FloatArray, tail: float) -> float:
        parts, options, theta, _ = fitted(u, tail)
        return run_held_out(baseline, unpack(u, tail)[0], parts, options, theta)

    u0 = np.array([basis.slip_level, np.log(basis.transition_velocity_m_s)] + (
        [] if at is None else [np.log(chosen[at].shape[key])]))  # fmt: skip
    lo, hi = np.array([b[0] for b in bounds]), np.array([b[1] for b in bounds])
    u0 = np.clip(u0, lo, hi)
    start = cost(u0, basis.transition_tail)
    found: list[tuple[FloatArray, float]] = []
    for tail in sorted(REFIT_TAILS, key=lambda t: t != basis.transition_tail):
        # from the best of a grid around the start (the level's valley in (C_v, v_t) is
        # narrow and curved: from the start alone the simplex stalls on it)
        grid = np.clip(u0 + np.array(list(itertools.product(*(
            (-d, 0.0, d) for d in JOINT_GRID_STEPS[:dims])))), lo, hi)  # fmt: skip
        u = min(grid, key=lambda g: cost(g, tail))
        # each first step away from the nearer bound (clipped at it, the simplex is flat)
        steps = np.asarray(JOINT_LEVEL_STEPS[:dims])
        steps = np.where(u + steps <= hi, steps, -steps)
        simplex = np.clip(u + np.vstack([np.zeros(dims), np.diag(steps)]), lo, hi)
        result = optimize.minimize(
            cost, u, args=(tail,), method="Nelder-Mead", bounds=bounds,
            options={"maxfev": JOINT_LEVEL_EVALS, "initial_simplex": simplex, "xatol": 0.01,
                     "fatol": 1e-4 * start},
        )  # fmt: skip
        if result.fun < start:
            found.append((result.x, tail))
    if not found:
        return None
    best = found[0] if len(found) == 1 else min(found, key=lambda f: held_out(*f))
    return unpack(*best)


def level_traded(chosen: Sequence[Option]) -> int | None:
    """The index in ``chosen`` of the effect whose shape is searched with the slip level
    (``Policy.level_shape``, the lowest ``level_rank`` first), or None."""
    traded = [(o.policy.level_rank, k) for k, o in enumerate(chosen) if o.policy.level_shape]
    return min(traded)[1] if traded else None


def run_held_out(
    baseline: Baseline, basis: Basis, parts: Sequence[FittedPart], chosen: Sequence[Option],
    theta: FloatArray,
) -> float:  # fmt: skip
    """The held-out RMS of the extended model of coefficients ``theta`` on ``basis`` as the
    compensator runs it (:func:`extended_force`), not as the design scales the GMS force
    (a level and a fall far from the truth's can hold out well in the design only)."""
    gms, extensions = extended_model(baseline, basis, parts, chosen, theta)
    return rms(held_residual(parts, [extended_force(fp, gms, extensions) for fp in parts]))


def extended_model(
    baseline: Baseline, basis: Basis, parts: Sequence[FittedPart], chosen: Sequence[Option],
    theta: FloatArray,
) -> tuple[GmsParams, list[fx.Effect]]:  # fmt: skip
    """The GMS and the effects of coefficients ``theta`` on ``basis``: ``chosen``'s, in
    its order, then a drive force's inertia."""
    n = baseline.n_gms
    w = widths(parts, chosen)
    base_width = parts[0].base.values.shape[1]
    extensions = [effect_of(o, chosen, theta, base_width, w) for o in chosen]
    return basis.gms(theta[:n]), extensions + drive_mass(baseline.prepared, theta, n)


def extended_force(fp: FittedPart, gms: GmsParams, extensions: Sequence[fx.Effect]) -> FloatArray:
    """The extended model (``gms``, then ``extensions``) simulated along ``fp``."""
    force = simulate(gms, fp.part.kin.position_m, fp.part.kin.velocity_m_s)[0]
    return fx.apply_extensions(extensions, dataclasses.replace(fp.ctx, gms_force_N=force, gms=gms))


def refine_slip_level(
    baseline: Baseline, cost: Callable[[tuple[FittedPart, ...]], float]
) -> Basis | None:
    """The basis's slip level and transition velocity (a free basis's transition shape
    too) searched again with ``cost`` (the training RMS with the kept effects present):
    bounded coordinate steps from the baseline's; None where a table's own is best. A
    table calibrated without the effects
    took part of a speed-dependent one into its level (a viscous slope raised it 1.12x,
    and a Stribeck fall 1.11x was then named to take it back at low speed)."""
    basis = baseline.basis
    vmax = max(float(np.max(np.abs(p.kin.velocity_m_s))) for p in baseline.prepared.parts)
    # with the kept effects present the cap is lifted (a third of the top speed: the EMPS
    # ball screw's level keeps rising above 2 mm/s)
    vt_range = transition_range(vmax, np.inf)
    if isinstance(basis, TableBasis):
        return _refine_table_level(baseline, basis, cost, vt_range)

    # a level met again (a step back, the vertex's C_v +- step) is not refitted
    @functools.cache
    def level_cost(level: Level) -> float:
        return cost(rebased(baseline, FreeBasis(basis.breakaway_m, *level)))

    best = coordinate_steps(
        (cost(baseline.parts), level_of(basis)), level_cost, REFINE_STEPS, vt_range
    )
    return FreeBasis(basis.breakaway_m, *best[1])


def _refine_table_level(
    baseline: Baseline, basis: TableBasis, cost: Callable[[tuple[FittedPart, ...]], float],
    vt_range: tuple[float, float],
) -> TableBasis | None:  # fmt: skip
    """The table's C_v and v_t stepped as :func:`refine_slip_level` steps a free basis's
    (None: none better than its own); its transition's shape, tail and law are the
    table's own."""
    p = basis.params
    start: Level = (p.slip_level, p.transition_velocity_m_s, p.transition_exponent,
                    p.transition_tail, p.limit_follows_level)  # fmt: skip

    def relevelled(level: Level) -> TableBasis:
        params = scaled(p, 1.0, 1.0, slip_level=level[0], transition_velocity_m_s=level[1])
        factor = basis.slip_level_factor * level[0] / p.slip_level
        return TableBasis(params, basis.presliding_factor, factor)

    @functools.cache
    def level_cost(level: Level) -> float:
        if level[2:] != start[2:]:
            return math.inf
        return cost(rebased(baseline, relevelled(level)))

    best = coordinate_steps((cost(baseline.parts), start), level_cost, REFINE_STEPS, vt_range)
    return relevelled(best[1]) if best[1] != start else None
