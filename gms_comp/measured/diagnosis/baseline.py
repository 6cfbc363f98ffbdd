"""Stage 2: the baseline model, calibrated on the training rows.

The blind baseline is a free NNLS GMS with the seed's velocity level (a sliding level
C_v >= 1 above the stick level, reached over v_t; :mod:`.slip_level`), fitted jointly
with the element limits: NNLS for each level, the level on a bounded grid then bounded
coordinate steps, the kept elements moved off the grid (:func:`refine_knots`), the level
stepped again. A trace whose only departure from a GMS is C_v is therefore ``none``.
Given a GMS table (the user's bearing), it is calibrated instead (:mod:`.basis`) and is
the baseline if its held-out RMS is within ``table_margin`` of the free GMS's.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gms_comp.gms import GmsParams
from gms_comp.measured.diagnosis.basis import (
    FreeBasis,
    Samples,
    Sensor,
    TableBasis,
    breakaway_grid,
    calibrate_table,
    presliding_length,
)
from gms_comp.measured.diagnosis.config import DiagnosisConfig
from gms_comp.measured.diagnosis.design import (
    Columns,
    FloatArray,
    GramDesign,
    PartDesign,
    rms,
    solve_gram_sse,
)
from gms_comp.measured.diagnosis.prepare import Part, Prepared
from gms_comp.measured.diagnosis.slip_level import (
    EXPONENT_RANGE,
    LAWS,
    REFINE_STEPS,
    SLIP_LEVELS,
    TAILS,
    TRANSITION_POINTS,
    Level,
    coordinate_steps,
    level_of,
    transition_range,
)
from gms_comp.measured.policies import policy
from gms_comp.runtime import effects as fx

Basis = FreeBasis | TableBasis

# The element grid in two passes: COARSE_ELEMENTS over the whole range of break-aways
# find where the limits are (a limit below SUPPORT_SHARE of the sum does not count);
# then the configured number over that range, widened by one coarse spacing either side.
COARSE_ELEMENTS = 8
SUPPORT_SHARE = 0.01
# Then the break-aways of the elements the grid fit keeps are moved off the grid (free
# knots): coordinate steps in log(break-away) of these sizes, at most KNOT_ROUNDS rounds
# each, inside the grid's range (a true element between grid points is otherwise carried
# by both, and a dwell's raised limit by neither).
KNOT_STEPS = (0.2, 0.1, 0.05)
KNOT_ROUNDS = 6
# The effect bases a part keeps for the rounds of the selection (about 180 columns of a
# 175 000-sample trace).
BASES_KEPT_BYTES = 256 << 20


@dataclass(frozen=True)
class FittedPart:
    """One part with the baseline's columns and its path quantities."""

    part: Part
    phi: FloatArray  # the GMS columns of the basis
    base: Columns  # phi (+ acceleration for a drive force)
    ctx: fx.Context  # path quantities, the GMS force the baseline's

    @functools.cached_property
    def _bases(self) -> dict[tuple[object, ...], FloatArray]:
        return {}

    def effect_basis(self, effect: type[fx.Effect], shape: Mapping[str, float]) -> FloatArray:
        """``effect``'s basis along this part at ``shape``, read-only and kept (a basis of
        the motion alone with the part, for every baseline) up to ``BASES_KEPT_BYTES``, the
        oldest dropped first: the selection scores a grid again in every round."""
        key = (effect.name, *sorted(shape.items()))
        kept = self._bases if policy(effect).basis_reads_gms else self.part.motion_bases
        if key not in kept:
            values = effect.basis(self.ctx, shape)
            values.flags.writeable = False
            while kept and sum(v.nbytes for v in kept.values()) + values.nbytes > BASES_KEPT_BYTES:
                del kept[next(iter(kept))]
            kept[key] = values
        return kept[key]


@dataclass(frozen=True)
class Baseline:
    """The output of :func:`fit_baseline`."""

    prepared: Prepared
    basis: Basis
    parts: tuple[FittedPart, ...]
    theta: FloatArray
    info: dict[str, Any]
    gms: GmsParams
    predictions: tuple[FloatArray, ...]
    heldout_rms_N: float
    presliding_m: float
    sliding_force_N: float

    @property
    def n_gms(self) -> int:
        """How many of the coefficients are the GMS's."""
        return self.parts[0].phi.shape[1]

    def to_json(self) -> dict[str, Any]:
        """The calibrated baseline's parameters for the diagnosis JSON."""
        return {
            "model": "free_nnls_gms" if isinstance(self.basis, FreeBasis) else "table_gms",
            **self.info,
            "force_kind": self.prepared.force_kind,
            "position": "encoder counts read as motion"
            if self.prepared.dequantised
            else "measured",
            "breakaway_m": self.basis.breakaway_m.tolist(),
            "limit_N": self.gms.limit_N.tolist(),
            "slip_level": self.gms.slip_level,
            "transition_velocity_m_s": self.gms.transition_velocity_m_s,
            "transition_exponent": self.gms.transition_exponent,
            "transition_tail": None if math.isinf(tail := self.gms.transition_tail) else tail,
            "limit_follows_level": self.gms.limit_follows_level,
            "sliding_force_N": self.sliding_force_N,
            "presliding_m": self.presliding_m,
            "mass_kg": float(self.theta[self.n_gms]) if self.prepared.drive else 0.0,
        }


def _design(part: Part, basis: Basis, drive: bool, nuisance: bool) -> tuple[int, Columns]:
    """One part's design and how many of its columns are the basis's: the basis's
    columns, the acceleration for a drive force, and with ``nuisance`` a viscous term
    (c v, c >= 0) and an offset of either sign, written after the basis's columns in one
    array (stacked afterwards, they copied the whole design)."""
    own = ([part.kin.acceleration_m_s2] if drive else []) + (
        [part.kin.velocity_m_s, np.ones(part.kin.velocity_m_s.size)] if nuisance else []
    )
    values = basis.columns(part.kin, len(own))
    n = values.shape[1] - len(own)
    for i, column in enumerate(own):
        values[:, n + i] = column
    lower = [0.0] * (n + int(drive)) + ([0.0, -np.inf] if nuisance else [])
    return n, Columns(values, np.array(lower))


def _designs(
    prepared: Prepared, basis: Basis, nuisance: bool = False
) -> list[tuple[FloatArray, Columns]]:
    """Each part's GMS columns and design (the same array where the design has no other
    columns)."""
    out = []
    for p in prepared.parts:
        n, cols = _design(p, basis, prepared.drive, nuisance)
        phi = cols.values if n == cols.values.shape[1] else np.ascontiguousarray(cols.values[:, :n])
        out.append((phi, cols))
    return out


def _part_designs(prepared: Prepared, basis: Basis, nuisance: bool = False) -> list[PartDesign]:
    return [
        PartDesign(_design(p, basis, prepared.drive, nuisance)[1], p.force_N, p.train, p.held)
        for p in prepared.parts
    ]


def _fit(
    prepared: Prepared, basis: Basis, nuisance: bool = False
) -> tuple[list[PartDesign], FloatArray, float]:
    designs = _part_designs(prepared, basis, nuisance)
    gram = GramDesign(designs)
    theta = gram.fit()
    return designs, theta, gram.train_rms(theta)


def fit_free(
    prepared: Prepared, breakaway_m: FloatArray, start: FreeBasis | None = None
) -> FreeBasis:
    """The free basis whose level (slip_level.Level) fits the training rows best, its
    limits by NNLS (a grid at exponent 2, then coordinate steps; or steps from ``start``'s).

    A viscous term (c >= 0) and an offset are fitted beside them in the search, then
    dropped: the slip level takes the saturating velocity dependence, a linear one is left
    to ``viscous`` (else C_v stands in for part of it), and an offset does not bend the slip
    level (a third of the level as offset put C_v where a Stribeck fall could not be kept)."""
    vmax = max(float(np.max(np.abs(p.kin.velocity_m_s))) for p in prepared.parts)
    vt_range = transition_range(vmax)
    sensed = None if start is None else start.sensed  # the columns through kept filters
    cache: dict[Level, float] = {}

    def cost(level: Level) -> float:
        key = (round(level[0], 6), round(level[1], 12), round(level[2], 6), level[3], level[4])
        if key not in cache:
            cache[key] = _fit(prepared, FreeBasis(breakaway_m, *level, sensed=sensed), True)[2]
        return cache[key]

    exponent = EXPONENT_RANGE[1]
    if start is None:
        best = (cost(flat := (1.0, vt_range[1], exponent, math.inf, False)), flat)
        for tail, law in [(tail, law) for tail in TAILS for law in LAWS]:
            for cv in SLIP_LEVELS:
                for vt in np.geomspace(*vt_range, TRANSITION_POINTS):
                    level = (cv, float(vt), exponent, tail, law)
                    best = min(best, (cost(level), level))
        steps: tuple[tuple[float, float], ...] = REFINE_STEPS
    else:
        level = level_of(start)
        best = (cost(level), level)
        steps = REFINE_STEPS[1:]
    best = coordinate_steps(best, cost, steps, vt_range)
    return FreeBasis(breakaway_m, *best[1], sensed=sensed)


def fit_baseline(prepared: Prepared, cfg: DiagnosisConfig, table: GmsParams | None) -> Baseline:
    """The free GMS with its slip level, or the calibrated ``table`` if its held-out RMS
    is within ``cfg.table_margin`` (relative) of the free GMS's; ``info`` holds both RMS
    values and the table's calibrated factors. Its slip level is searched from the grid
    even where another fit on the same motion is known (stepped from it, a reading of the
    encoder's counts lost the margin it holds out by)."""
    free = _free_basis(prepared, cfg.n_elements)
    designs, theta, _ = _fit(prepared, free, nuisance=True)
    free = refine_knots(prepared, free, theta)
    free = fit_free(prepared, free.breakaway_m, start=free)
    designs, theta, _ = _fit(prepared, free)
    free_rms = rms(GramDesign(designs).held_residual(theta))
    info: dict[str, Any] = {"source": "free_nnls", "free_nnls_heldout_rms_N": free_rms}
    basis: Basis = free
    if table is not None:
        samples = [Samples(p.kin, p.force_N, p.train) for p in prepared.parts]
        calibrated = calibrate_table(table, samples, prepared.drive)
        t_designs, t_theta, _ = _fit(prepared, calibrated)
        table_rms = rms(GramDesign(t_designs).held_residual(t_theta))
        info.update(
            table_heldout_rms_N=table_rms,
            level_factor=float(t_theta[0]),
            presliding_factor=calibrated.presliding_factor,
            slip_level_factor=calibrated.slip_level_factor,
            transition_velocity_m_s=calibrated.params.transition_velocity_m_s,
        )
        if table_rms <= (1.0 + cfg.table_margin) * free_rms:
            basis, theta, info["source"] = calibrated, t_theta, "table"
    return _baseline(prepared, basis, theta, info)


def _free_basis(prepared: Prepared, n_elements: int) -> FreeBasis:
    """The free basis in two passes (``COARSE_ELEMENTS``, then ``n_elements`` where the
    coarse limits are; one pass if ``n_elements`` is not more than the coarse count)."""
    kin, resolution = prepared.main.kin, prepared.position_resolution_m
    coarse = breakaway_grid(kin, min(n_elements, COARSE_ELEMENTS), resolution)
    free = fit_free(prepared, coarse)
    if n_elements <= COARSE_ELEMENTS:
        return free
    # the coarse limits with the viscous term and the offset beside them (without, an
    # offset of 12 % of the level left no element above 8 um for a truth's 26 um, and the
    # extended model missed by 6.5 x the noise after every sine reversal)
    _, theta, _ = _fit(prepared, free, nuisance=True)
    limits = theta[: coarse.size]
    where = np.flatnonzero(limits > SUPPORT_SHARE * max(float(np.sum(limits)), 1e-300))
    if where.size == 0:
        return free
    spacing = float(coarse[1] / coarse[0])
    lo = max(float(coarse[where[0]]) / spacing, float(coarse[0]))
    hi = min(float(coarse[where[-1]]) * spacing, float(coarse[-1]))
    return fit_free(prepared, np.geomspace(lo, hi, n_elements), start=free)


def refine_knots(prepared: Prepared, basis: FreeBasis, theta: FloatArray) -> FreeBasis:
    """``basis`` with the break-aways of the elements that have a limit in ``theta``
    moved to fit the training rows best (bounded coordinate steps, ``KNOT_STEPS``); the
    others stay where they are (a fit through a filter uses elements the unfiltered one
    left empty). A viscous term and an offset are fitted beside the elements (in
    ``theta`` too), so that they do not bend the break-aways."""
    n = basis.breakaway_m.size
    knots = basis.breakaway_m.copy()
    active = [int(i) for i in np.flatnonzero(theta[:n] > 0.0)]
    lo, hi = float(basis.breakaway_m[0]), float(basis.breakaway_m[-1])
    start = dataclasses.replace(basis, breakaway_m=knots)
    gram = GramDesign(_part_designs(prepared, start, nuisance=True))

    def columns(ds: list[float]) -> list[FloatArray]:
        # one kernel pass for all of a round's trial break-aways (the elements are
        # independent; a pass of 12 costs about 3 of one), each a contiguous column
        many = dataclasses.replace(basis, breakaway_m=np.array(ds))
        return [many.columns(p.kin, order="F") for p in prepared.parts]

    best = solve_gram_sse(gram.gram, gram.rhs, gram.lower)[1]
    for step in KNOT_STEPS:
        for _ in range(KNOT_ROUNDS):
            # each knot moves at most once per round: its trials are known at its start,
            # and their cross products are made at once (one by one, each read the design)
            trials = [
                (i, d)
                for i in active
                for d in dict.fromkeys(
                    float(np.clip(knots[i] * np.exp(s), lo, hi)) for s in (-step, step)
                )
                if d != knots[i]
            ]
            if not trials:
                break
            values = columns([d for _, d in trials])
            cross, inner, rhs = gram.cross_products(values)
            moved: dict[int, int] = {}  # knot -> the trial it moved to
            for j, (i, d) in enumerate(trials):
                if i in moved:
                    continue  # moved down: the step up leads back
                row = cross[:, j].copy()
                for k, jk in moved.items():
                    row[k] = inner[jk, j]
                row[i] = inner[j, j]
                g, r = gram.gram.copy(), gram.rhs.copy()
                g[i, :] = g[:, i] = row
                r[i] = rhs[j]
                trial = solve_gram_sse(g, r, gram.lower)[1]
                if trial < best:
                    best, knots[i], moved[i] = trial, d, j
                    gram.replace_column(i, [v[:, j] for v in values], (g, r))
            if not moved:
                break
    order = np.argsort(knots)
    return dataclasses.replace(basis, breakaway_m=knots[order])


def _baseline(
    prepared: Prepared, basis: Basis, theta: FloatArray, info: dict[str, Any],
    designs: list[tuple[FloatArray, Columns]] | None = None,
) -> Baseline:  # fmt: skip
    designs = designs or _designs(prepared, basis)
    n_gms = designs[0][0].shape[1]
    gms = basis.gms(theta[:n_gms])
    parts = []
    for p, (phi, cols) in zip(prepared.parts, designs, strict=True):
        ctx = dataclasses.replace(prepared.context(p, phi @ theta[:n_gms]), gms=gms)
        parts.append(FittedPart(p, phi, cols, ctx))
    predictions = tuple(fp.base.values @ theta for fp in parts)
    return Baseline(
        prepared, basis, tuple(parts), theta, info, gms, predictions,
        heldout_rms_N=rms(held_residual(parts, predictions)), presliding_m=presliding_length(gms),
        sliding_force_N=float(np.sum(gms.limit_N)) * gms.slip_level,
    )  # fmt: skip


def drive_mass(prepared: Prepared, theta: FloatArray, n_gms: int) -> list[fx.Effect]:
    """A drive force's mass (the coefficient after the GMS's) as an effect; none for a
    friction force."""
    return [fx.Inertia(float(theta[n_gms]))] if prepared.drive else []


def held_residual(parts: Sequence[FittedPart], predictions: Sequence[FloatArray]) -> FloatArray:
    """What ``predictions`` (one per part) leave on the parts' held-out rows, in order."""
    pairs = zip(parts, predictions, strict=True)
    return np.concatenate([fp.part.force_N[fp.part.held] - y[fp.part.held] for fp, y in pairs])


def fitted_on(prepared: Prepared, basis: Basis, info: dict[str, Any]) -> Baseline:
    """The baseline on ``basis``, its coefficients fitted on ``prepared``'s training rows."""
    designs = _designs(prepared, basis)
    gram = GramDesign([
        PartDesign(cols, p.force_N, p.train, p.held)
        for p, (_, cols) in zip(prepared.parts, designs, strict=True)
    ])  # fmt: skip
    return _baseline(prepared, basis, gram.fit(), info, designs)


def placed_on(prepared: Prepared, fitted: Baseline) -> Baseline:
    """``fitted``'s basis and coefficients (its GMS force in the path) on ``prepared``."""
    return _baseline(prepared, fitted.basis, fitted.theta, fitted.info)


def refit_gms_force(
    parts: tuple[FittedPart, ...], theta: FloatArray, basis: Basis
) -> tuple[FittedPart, ...]:
    """The parts with their path context's GMS (force and elements) from the
    coefficients ``theta`` of ``basis``."""
    n = parts[0].phi.shape[1]
    gms = basis.gms(theta[:n])
    return tuple(
        dataclasses.replace(
            fp, ctx=dataclasses.replace(fp.ctx, gms_force_N=fp.phi @ theta[:n], gms=gms)
        )
        for fp in parts
    )


def rebased(baseline: Baseline, basis: Basis) -> tuple[FittedPart, ...]:
    """The parts of :func:`rebased_gram`."""
    return rebased_gram(baseline, basis)[0]


def rebased_gram(baseline: Baseline, basis: Basis) -> tuple[tuple[FittedPart, ...], GramDesign]:
    """The baseline's parts on another basis (the same path quantities; the GMS force
    that basis fits alone), and the Gram matrix of their base columns it was fitted on."""
    designs = _designs(baseline.prepared, basis)
    parts = tuple(
        dataclasses.replace(fp, phi=phi, base=cols)
        for fp, (phi, cols) in zip(baseline.parts, designs, strict=True)
    )
    gram = GramDesign(
        [PartDesign(fp.base, fp.part.force_N, fp.part.train, fp.part.held) for fp in parts]
    )
    return refit_gms_force(parts, gram.fit(), basis), gram


def fitted_through(baseline: Baseline, sensed: Sensor, names: Sequence[str]) -> Baseline:
    """``baseline`` (a free GMS) with its knots, slip level (from its own) and limits fitted
    again with its element columns through ``sensed`` (the kept filters ``names``: elements
    fitted before a sensor filter was known bend to its lag); the basis kept without
    ``sensed`` (the design applies the kept filters to every column). The search's viscous
    and offset columns are not passed through the filter."""
    assert isinstance(baseline.basis, FreeBasis)
    prepared = baseline.prepared
    start = dataclasses.replace(baseline.basis, sensed=sensed)
    _, theta, _ = _fit(prepared, start, nuisance=True)
    start = refine_knots(prepared, start, theta)
    moved = fit_free(prepared, start.breakaway_m, start=start)
    _, theta, _ = _fit(prepared, moved)
    info = {**baseline.info, "fitted_through": list(names)}
    return _baseline(prepared, dataclasses.replace(moved, sensed=None), theta, info)
