"""The slip level's bounded search over (C_v, v_t, transition exponent and tail): the grid the
baseline starts from, then coordinate steps and a parabola in C_v, each trial costed by
the caller (the baseline's NNLS fit, or the extended model's training RMS in the refit)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from gms_comp.measured.diagnosis.basis import FreeBasis

# The level's grid: C_v on SLIP_LEVELS (1.05 in it: a C_v of 1.047 fitted as 1 left a
# Stribeck fall named on an effect-free trace) within SLIP_LEVEL_RANGE, v_t on a log grid
# of TRANSITION_POINTS over TRANSITION_FRACTIONS of the top speed, then at most
# REFINE_ROUNDS rounds of coordinate steps (REFINE_STEPS: C_v +-, v_t and exponent x/).
# v_t is at most a third of the top speed and MAX_TRANSITION_M_S (the contact goes from
# stick to slip at micro-slip speeds: a level still changing above a few mm/s is a
# catalogue effect's, viscous or stribeck, and the two traded against it when it was free).
SLIP_LEVELS = (1.05, 1.15, 1.25, 1.4, 1.9)
SLIP_LEVEL_RANGE = (1.0, 3.0)
MIN_TRANSITION_M_S = 1e-7
TRANSITION_FRACTIONS = (1 / 5000, 1 / 3)
TRANSITION_POINTS = 8
MAX_TRANSITION_M_S = 2e-3
REFINE_ROUNDS = 12
REFINE_STEPS = ((0.1, 2.0), (0.05, 1.4), (0.02, 1.15))
# The approach's shape: the seed's Gaussian (exponent 2), stepped down to the exponential
# (1): a level that approaches C_v over a decade of speed is within a few per cent of the
# exponential from v_t up, and a Gaussian left it to a viscous term.
EXPONENT_RANGE = (1.0, 2.0)
# Its tails (GmsParams.transition_tail): the blind baseline searches the exponential
# approach only; the refit's joint search (REFIT_TAILS) also the rational one,
# 1 / (1 + u^delta) (Hess and Soom's Lorentzian at delta 2), once the names are chosen:
# searched blind it found more dwell gains but named a Stribeck fall on three traces
# without one.
RATIONAL_TAIL = 1.0
TAILS = (math.inf,)
REFIT_TAILS = (math.inf, RATIONAL_TAIL)
# Its laws (GmsParams.limit_follows_level): the seed's (a slipping element carries C_v W_i
# at once) and a play operator whose limit follows the level; the grid is laid out for
# each (held to the seed's law, a play-law truth biased a mass and hid dwell gains).
LAWS = (False, True)


Level = tuple[float, float, float, float, bool]  # C_v, v_t, exponent, tail, law


def level_of(basis: FreeBasis) -> Level:
    """The free basis's (C_v, v_t, exponent, tail, law)."""
    return (
        basis.slip_level,
        basis.transition_velocity_m_s,
        basis.transition_exponent,
        basis.transition_tail,
        basis.limit_follows_level,
    )


def coordinate_steps(
    best: tuple[float, Level], cost: Callable[[Level], float],
    steps: tuple[tuple[float, float], ...], vt_range: tuple[float, float],
) -> tuple[float, Level]:  # fmt: skip
    """Coordinate steps (``steps``: C_v +-, v_t and exponent x/) from ``best`` (cost,
    level) while they lower ``cost``, at most ``REFINE_ROUNDS`` rounds in all; then
    :func:`slip_level_vertex`."""
    rounds = 0
    for d_cv, factor in steps:
        while rounds < REFINE_ROUNDS:
            rounds += 1
            before = best
            for level in neighbours(best[1], d_cv, factor, vt_range):
                if level != best[1]:  # a step clipped at a bound
                    best = min(best, (cost(level), level))
            if best == before:
                break
    return slip_level_vertex(best, cost, steps[-1][0])


def slip_level_vertex(
    best: tuple[float, Level], cost: Callable[[Level], float], d_cv: float
) -> tuple[float, Level]:
    """``best`` or the level with C_v at the vertex of the parabola through the squared
    costs at C_v +- ``d_cv`` (within the step), whichever costs less (the cost is sharp in
    C_v: the steps stop a fraction of a step from its minimum)."""
    cv, vt, ex, tail, law = best[1]
    lo, hi = SLIP_LEVEL_RANGE
    if not lo + d_cv <= cv <= hi - d_cv:
        return best
    c_lo, c_hi = (cost((cv + d, vt, ex, tail, law)) ** 2 for d in (-d_cv, d_cv))
    curvature = c_lo - 2.0 * best[0] ** 2 + c_hi
    if curvature <= 0.0:
        return best
    shift = float(np.clip(0.5 * d_cv * (c_lo - c_hi) / curvature, -d_cv, d_cv))
    level = (cv + shift, vt, ex, tail, law)
    return min(best, (cost(level), level))


def transition_range(vmax: float, cap: float = MAX_TRANSITION_M_S) -> tuple[float, float]:
    """The bounds of v_t for a trace whose top speed is ``vmax`` (see the constants)."""
    hi = max(min(vmax * TRANSITION_FRACTIONS[1], cap), 10 * MIN_TRANSITION_M_S)
    return max(vmax * TRANSITION_FRACTIONS[0], MIN_TRANSITION_M_S), hi


def neighbours(
    level: Level, d_cv: float, factor: float, vt_range: tuple[float, float]
) -> list[Level]:
    """One coordinate step either way from (C_v, v_t, exponent), inside the bounds, and
    the other tails and laws."""
    cv, vt, ex, tail, law = level
    lo, hi = SLIP_LEVEL_RANGE
    return (
        [(min(max(cv + d, lo), hi), vt, ex, tail, law) for d in (-d_cv, d_cv)]
        + [(cv, min(max(vt * f, vt_range[0]), vt_range[1]), ex, tail, law)
           for f in (1 / factor, factor)]
        + [(cv, vt, min(max(ex * f, EXPONENT_RANGE[0]), EXPONENT_RANGE[1]), tail, law)
           for f in (1 / factor, factor)]
        + [(cv, vt, ex, other, law) for other in TAILS if other != tail]
        + [(cv, vt, ex, tail, other) for other in LAWS if other != law]
    )  # fmt: skip
