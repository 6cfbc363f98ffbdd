"""Stage 5: the kept effects refitted jointly, and the extended model run as the
compensator runs it.

The effects that scale the friction (stribeck, dwell_time, drift) are columns of the GMS
force; it is updated to the jointly fitted GMS and the fit repeated (``JOINT_REFITS``
times), so that they scale the force the extended model will run with. The shapes of
``REFIT_SHAPES`` are searched again each time by training RMS: the selection chose them
by held-out RMS with the baseline's GMS force, where a dwell's gain and time constant
trade off (tau came out 15-30 % high on simulated traces).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.gms import GmsParams, simulate
from gms_comp.measured.diagnosis.baseline import (
    Baseline,
    FittedPart,
    rebased,
    refine_slip_level,
    refit_gms_force,
)
from gms_comp.measured.diagnosis.candidates import Option, Scorer, design, effect_of, widths
from gms_comp.measured.diagnosis.config import DiagnosisConfig
from gms_comp.measured.diagnosis.design import GramDesign, rms, train_rms
from gms_comp.measured.diagnosis.selection import Selection, admissible, local_search
from gms_comp.runtime import effects as fx

JOINT_REFITS = 3
REFIT_SHAPES = (fx.DwellTime, fx.Drift)


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


def refit(selection: Selection, cfg: DiagnosisConfig) -> Extended:
    """All coefficients fitted jointly with every kept effect present; the extended
    model (GMS kernel, then the effects) simulated along every part.

    Once the slip level is refined with the kept effects present, a later-ranked effect
    that is no longer admissible on top of the others (it stood in for a slip level the
    blind baseline had not found) is dropped."""
    baseline = selection.baseline
    chosen = list(selection.chosen)
    history = list(selection.heldout_rms_N)
    parts = baseline.parts
    basis = baseline.basis
    if chosen:
        slip = refine_slip_level(baseline, lambda p: _train_rms(p, chosen))
        if slip is not None:
            basis, parts = slip, rebased(baseline, slip)
        for i in range(len(chosen) - 1, 0, -1):
            others = chosen[:i] + chosen[i + 1 :]
            trial = Scorer(parts, others)
            if not admissible(cfg, trial, trial.score(chosen[i]), baseline.sliding_force_N):
                del chosen[i], history[i]
    theta = GramDesign(design(parts, chosen)).fit()
    for _ in range(JOINT_REFITS if chosen else 0):
        parts = refit_gms_force(parts, theta)
        chosen = _refine_shapes(parts, chosen, baseline.presliding_m)
        theta = GramDesign(design(parts, chosen)).fit()
    n = baseline.n_gms
    base_width = parts[0].base.values.shape[1]
    w = widths(parts, chosen)
    ranked = tuple(
        Ranked(effect_of(o, chosen, theta, base_width, w), h)
        for o, h in zip(chosen, history, strict=True)
    )
    gms = basis.gms(theta[:n])
    extensions = [r.effect for r in ranked]
    if baseline.prepared.drive:
        extensions.append(fx.Inertia(float(theta[n])))
    predictions = tuple(_run(fp, gms, extensions) for fp in parts)
    held = np.concatenate(
        [
            fp.part.force_N[fp.part.held] - y[fp.part.held]
            for fp, y in zip(parts, predictions, strict=False)
        ]
    )
    return Extended(baseline, ranked, gms, tuple(extensions), predictions, rms(held), held)


def _train_rms(parts: Sequence[FittedPart], chosen: Sequence[Option]) -> float:
    designs = design(parts, chosen)
    return train_rms(designs, GramDesign(designs).fit())


def _refine_shapes(
    parts: Sequence[FittedPart], chosen: list[Option], presliding_m: float
) -> list[Option]:
    out = list(chosen)
    for i, opt in enumerate(chosen):
        if opt.effect not in REFIT_SHAPES:
            continue

        def cost(trial: Option, i: int = i) -> float:
            return _train_rms(parts, [*out[:i], trial, *out[i + 1 :]])

        bounds = opt.effect.shape_bounds(parts[0].ctx, presliding_m)
        out[i] = local_search(opt, cost, cost(opt), bounds)[0]
    return out


def _run(fp: FittedPart, gms: GmsParams, extensions: Sequence[fx.Effect]) -> FloatArray:
    force = simulate(gms, fp.part.kin.position_m, fp.part.kin.velocity_m_s)[0]
    return fx.apply_extensions(extensions, dataclasses.replace(fp.ctx, gms_force_N=force))
