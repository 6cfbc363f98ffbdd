"""An effect scored with the baseline's slip level free (``Policy.free_level``: a
Stribeck fall).

The blind baseline fits its slip level C_v alone, and a Stribeck fall drags it: with
friction rising from stick to a sliding level C_v above it and falling again towards
sliding speed (stribeck-120 of the independent generator: C_v 1.14, v_t 0.35 mm/s,
ratio 1.24 at 6.4 mm/s), the GMS alone fits best with C_v 1, and a Stribeck column on
that level lowers the held-out RMS by 2.5 % only (0.578 -> 0.564 N; a drift was named).
With the level at C_v 1.1 it lowers it to 0.295 N. So where the design still leaves
above the noise (``free_level_ratio``), Stribeck is also scored on the baseline
refitted at each level of a grid (``FREE_LEVEL_STEPS`` x ``FREE_TRANSITIONS``, about
0.2 s each on 170 000 samples), in the first ``free_level_rounds`` rounds of the
selection where the round's best is not Stribeck at the baseline's level (that one's
level is searched with it in the refit; taken over by the level-free search, stribeck-105
of the independent generator came out with ratio - 1 0.61 off, 0.19 from the refit).
The selection keeps the best if it beats by the margin every other trial of its round
and the level's own gain (:func:`~.selection._free_level`), and goes on from that level.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from gms_comp.measured.diagnosis.baseline import Baseline, fitted_on, refit_gms_force
from gms_comp.measured.diagnosis.basis import FreeBasis
from gms_comp.measured.diagnosis.candidates import Scorer, Trial, options
from gms_comp.measured.diagnosis.slip_level import SLIP_LEVEL_RANGE, transition_range
from gms_comp.runtime import effects as fx

# The grid of slip levels: C_v above the baseline's by these steps (a fall towards
# sliding speed drags the level down: on eight stribeck traces of the independent
# generator the best level lay 0.05-0.2 above the baseline's), the transition velocity
# on a log grid over the baseline's range, the transition's shape the baseline's.
FREE_LEVEL_STEPS = (0.05, 0.1, 0.15, 0.2, 0.3)
FREE_TRANSITIONS = 3
# Then, at the best level, the transition velocity halfway (in log) to the grid's points
# either side: the grid's points are 15 x apart (on pair_offset_stribeck-229, C_v 1.136
# reached over 0.64 mm/s, a fall of ratio 1.12 at 2.7 mm/s, Stribeck held out 0.1902 N
# on the grid's best, 0.132 mm/s, beside 0.1951 N for drift at the baseline's level: not
# the margin, `offset` alone was named; 0.1723 N at 0.51 mm/s).


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
    the grid's levels, by (C_v, transition velocity), kept across the selection's rounds
    (one baseline on one level does not depend on the effects chosen; 15 fits a round,
    and 2 around the best)."""
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
