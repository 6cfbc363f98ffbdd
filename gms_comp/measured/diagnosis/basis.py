"""The GMS part of the baseline: linear in a few non-negative coefficients, so the
catalogue effects are fitted as extra columns of one design.

- :class:`FreeBasis`: one column per element of a log grid of break-away displacements,
  its coefficient the element's limit W_i, the seed's slip level C_v >= 1 reached over a
  transition velocity shared by all (an element's force is W phi(x, v), phi its unit
  output, computed by the project's GMS kernel).
- :class:`TableBasis`: one column, a GMS table's force (the user's bearing) with its
  presliding scale and velocity dependence calibrated on the training samples; the
  coefficient is the level factor on every W_i, its parameters meaningful to the user.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from scipy import optimize

from gms_comp.arrays import BoolArray, FloatArray
from gms_comp.gms import GmsParams, scaled, simulate, simulate_elements
from gms_comp.measured.diagnosis.design import solve
from gms_comp.measured.diagnosis.motion import Kinematics

# Bounds of the calibrated factors: presliding scale (on every W_i / k_i), slip level
# C_v, and the transition velocity (at most the trace's top speed).
PRESLIDING_BOUNDS = (1e-2, 1e2)
SLIP_LEVEL_BOUNDS = (0.2, 5.0)
MIN_TRANSITION_VELOCITY_M_S = 1e-9


def breakaway_grid(kin: Kinematics, n_elements: int, resolution_m: float) -> FloatArray:
    """Log-spaced element break-away displacements from the position resolution up to a
    tenth of the stroke (at most 1 mm: ball guides reach gross sliding well before)."""
    resolution = max(resolution_m, 1e-8)
    stroke = float(np.ptp(kin.position_m))
    hi = max(min(1e-3, 0.1 * stroke), 20 * resolution)
    return np.geomspace(2 * resolution, hi, n_elements)


# A linear filter on design columns (values, sample time in s).
Sensor = Callable[[FloatArray, float], FloatArray]


@dataclass(frozen=True)
class FreeBasis:
    """Elements on a fixed grid of break-away displacements, sharing the slip level
    ``slip_level`` (C_v) reached over ``transition_velocity_m_s`` with the shape
    ``transition_exponent``, tail ``transition_tail`` and law ``limit_follows_level``
    (:class:`~gms_comp.gms.GmsParams`); coefficients: the limits W_i."""

    breakaway_m: FloatArray
    slip_level: float = 1.0
    transition_velocity_m_s: float = 1e-4
    transition_exponent: float = 2.0
    transition_tail: float = math.inf
    limit_follows_level: bool = False
    # while the baseline is fitted again through a kept filter (a sensor low-pass): the
    # element columns through it (the spare ones are not; see diagnosis.sensed)
    sensed: Sensor | None = field(default=None, compare=False, repr=False)

    def columns(
        self, kin: Kinematics, spare: int = 0, order: Literal["C", "F"] = "C"
    ) -> FloatArray:
        """phi_i: the force of a unit-limit element with break-away ``breakaway_m[i]``
        (then ``spare`` columns not set; ``order``: :func:`~gms_comp.gms.simulate_elements`),
        through ``sensed`` if set."""
        n = self.breakaway_m.size
        unit = self.gms(np.ones(n))
        out = simulate_elements(unit, kin.position_m, kin.velocity_m_s, spare, order)
        if self.sensed is not None:  # at the mean interval, as the design's filters
            dt = (kin.time_s[-1] - kin.time_s[0]) / max(kin.time_s.size - 1, 1)
            out[:, :n] = self.sensed(out[:, :n], float(dt))
        return out

    def gms(self, coefficients: FloatArray, breakaway_m: FloatArray | None = None) -> GmsParams:
        """The GMS whose element i has limit ``coefficients[i]``; an element with zero
        limit keeps a nominal stiffness (the kernel wants k > 0)."""
        delta = self.breakaway_m if breakaway_m is None else breakaway_m
        w = np.maximum(coefficients, 0.0)
        k = np.where(w > 0, w, 1.0) / delta
        return GmsParams(
            k,
            w,
            slip_level=self.slip_level,
            transition_velocity_m_s=self.transition_velocity_m_s,
            transition_exponent=self.transition_exponent,
            transition_tail=self.transition_tail,
            limit_follows_level=self.limit_follows_level,
        )


@dataclass(frozen=True)
class TableBasis:
    """A calibrated table GMS; its one coefficient scales every limit W_i (and k_i, so
    the break-away displacements stay)."""

    params: GmsParams
    presliding_factor: float
    slip_level_factor: float

    @property
    def breakaway_m(self) -> FloatArray:
        """W_i / k_i of every element."""
        return np.asarray(self.params.limit_N / self.params.stiffness_N_per_m)

    def columns(self, kin: Kinematics, spare: int = 0) -> FloatArray:
        """The table's force as one column (then ``spare`` columns not set)."""
        out = np.empty((kin.position_m.size, 1 + spare))
        out[:, 0] = simulate(self.params, kin.position_m, kin.velocity_m_s)[0]
        return out

    def gms(self, coefficients: FloatArray) -> GmsParams:
        """The table with every limit scaled by ``coefficients[0]``."""
        return scaled(self.params, float(coefficients[0]), 1.0)


@dataclass(frozen=True)
class Samples:
    """Where a basis is calibrated: one trace's kinematics, force and training mask."""

    kin: Kinematics
    force_N: FloatArray
    train: BoolArray


def calibrate_table(table: GmsParams, samples: Sequence[Samples], drive: bool) -> TableBasis:
    """The presliding scale, slip level and transition velocity of ``table`` that fit the
    training samples best, by bounded least squares; the level (and the mass for a drive
    force) is solved linearly inside every evaluation, each a batch :func:`simulate` run."""
    vmax = max(float(np.max(np.abs(s.kin.velocity_m_s))) for s in samples)
    vt_hi = max(vmax, 2 * MIN_TRANSITION_VELOCITY_M_S)

    def candidate(u: FloatArray) -> GmsParams:
        return scaled(
            table, 1.0, math.exp(u[0]), slip_level=float(u[1]),
            transition_velocity_m_s=math.exp(u[2]),
        )  # fmt: skip

    def residual(u: FloatArray) -> FloatArray:
        params = candidate(u)
        cols = [_columns(params, s, drive) for s in samples]
        a = np.concatenate(cols)
        y = np.concatenate([s.force_N[s.train] for s in samples])
        return y - a @ solve(a, y, np.zeros(a.shape[1]))

    lower = [
        math.log(PRESLIDING_BOUNDS[0]),
        SLIP_LEVEL_BOUNDS[0],
        math.log(MIN_TRANSITION_VELOCITY_M_S),
    ]
    upper = [math.log(PRESLIDING_BOUNDS[1]), SLIP_LEVEL_BOUNDS[1], math.log(vt_hi)]
    start = np.clip([0.0, table.slip_level, math.log(table.transition_velocity_m_s)], lower, upper)
    # the slip level has little effect where the transition velocity is far above the
    # speeds of the trace: finite differences of a few per cent see it anyway
    res = optimize.least_squares(residual, start, bounds=(lower, upper), diff_step=1e-2)
    best = candidate(res.x)
    return TableBasis(best, math.exp(res.x[0]), best.slip_level / table.slip_level)


def _columns(params: GmsParams, s: Samples, drive: bool) -> FloatArray:
    force = simulate(params, s.kin.position_m, s.kin.velocity_m_s)[0]
    cols = [force, s.kin.acceleration_m_s2] if drive else [force]
    return np.column_stack(cols)[s.train]


def presliding_length(params: GmsParams) -> float:
    """Displacement by which the virgin curve reaches 90 % of its level: the break-away
    W_i / k_i by which 90 % of the limits have been reached."""
    breakaway = params.limit_N / params.stiffness_N_per_m
    order = np.argsort(breakaway)
    total = float(np.sum(params.limit_N))
    if total <= 0:
        return float(np.max(breakaway))
    reach = np.cumsum(params.limit_N[order]) / total
    return float(breakaway[order][np.searchsorted(reach, 0.9)])
