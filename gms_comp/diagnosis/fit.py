"""Least-squares machinery of the diagnosis: the free GMS basis, bounded solves, grids.

A Maxwell-slip element with break-away displacement delta = W/k has a force W phi(x),
where phi, the element's normalised play-operator output, depends on delta only. With
the deltas fixed on a log grid the GMS force is linear in the limits W_i >= 0, so the
baseline is a non-negative least-squares fit (the spec's free NNLS GMS) and every
catalogue effect adds columns to the same design. phi is computed by the project's GMS
kernel (:func:`gms_comp.gms.simulate`) with one unit element.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from .. import effects as fx
from ..gms import GmsParams, simulate
from .motion import BoolArray, FloatArray, Kinematics


def position_resolution(position_m: FloatArray) -> float:
    """The smallest position step the sensor reports (the 5th percentile of the
    nonzero steps of the raw position)."""
    steps = np.abs(np.diff(position_m))
    steps = steps[steps > 0]
    return float(np.percentile(steps, 5)) if steps.size else 0.0


def breakaway_grid(kin: Kinematics, n_elements: int) -> FloatArray:
    """Log-spaced element break-away displacements from the position resolution up to a
    tenth of the stroke (at most 1 mm: ball guides reach gross sliding well before)."""
    steps = np.abs(np.diff(kin.position_m))
    resolution = max(float(np.percentile(steps[steps > 0], 5)) if np.any(steps > 0) else 0, 1e-8)
    stroke = float(np.ptp(kin.position_m))
    hi = max(min(1e-3, 0.1 * stroke), 20 * resolution)
    return np.geomspace(2 * resolution, hi, n_elements)


def element_basis(kin: Kinematics, breakaway_m: FloatArray) -> FloatArray:
    """Columns phi_i: the force of a unit-limit element with break-away ``breakaway_m[i]``."""
    cols = [
        simulate(GmsParams(np.array([1.0 / d]), np.array([1.0])), kin.position_m, kin.velocity_m_s)[
            0
        ]
        for d in breakaway_m
    ]
    return np.column_stack(cols)


def gms_from_limits(breakaway_m: FloatArray, limits_N: FloatArray) -> GmsParams:
    """The GMS whose element i has limit ``limits_N[i]`` and break-away ``breakaway_m[i]``.

    An element with zero limit keeps a nominal stiffness (the kernel wants k > 0)."""
    w = np.maximum(limits_N, 0.0)
    k = np.where(w > 0, w, 1.0) / breakaway_m
    return GmsParams(k, w)


def solve(a: FloatArray, y: FloatArray, lower: FloatArray) -> FloatArray:
    """min ||a c - y|| with c >= lower (use -inf for free coefficients).

    The problem is reduced by a QR factorisation first, so the bounded solver works on a
    square system whatever the number of samples."""
    q, r = np.linalg.qr(a)
    rhs = q.T @ y
    if np.all(np.isneginf(lower)):
        return np.asarray(np.linalg.lstsq(r, rhs, rcond=None)[0], dtype=np.float64)
    res = optimize.lsq_linear(r, rhs, bounds=(lower, np.full_like(lower, np.inf)), method="bvls")
    return np.asarray(res.x, dtype=np.float64)


def rms(x: FloatArray) -> float:
    return float(np.sqrt(np.mean(x * x))) if x.size else 0.0


@dataclass(frozen=True)
class Columns:
    """Design columns of one model part with the lower bounds of their coefficients."""

    values: FloatArray  # (n, k)
    lower: FloatArray  # (k,)


def effect_columns(effect: type[fx.Effect], ctx: fx.Context, shape: Mapping[str, float]) -> Columns:
    """An additive effect's basis with its sign constraints (spec: transient A > 0;
    a dwell gain and an inertia are not negative)."""
    values = effect.basis(ctx, shape)
    nonneg = effect in (fx.ReversalTransient, fx.DwellTime, fx.Inertia)
    return Columns(values, np.full(values.shape[1], 0.0 if nonneg else -np.inf))


def shape_grid(
    effect: type[fx.Effect], kin: Kinematics, ctx: fx.Context, residual_N: FloatArray,
    moving: BoolArray, breakaway_m: float,
) -> Iterator[dict[str, float]]:  # fmt: skip
    """Candidate values of an effect's nonlinear shape parameters."""
    duration = float(kin.time_s[-1] - kin.time_s[0])
    vmax = float(np.max(np.abs(kin.velocity_m_s)))
    stroke = float(np.ptp(kin.position_m))
    if effect is fx.Stribeck:
        for v_s in np.geomspace(vmax / 200, vmax / 2, 10):
            yield {"v_s_m_per_s": float(v_s)}
    elif effect is fx.DwellTime:
        for tau in np.geomspace(1e-3, 1e1, 9):
            for scale in (0.5, 1.0, 2.0):
                yield {"tau_s": float(tau), "breakaway_m": scale * breakaway_m}
    elif effect is fx.PositionRipple:
        for lam in ripple_wavelengths(kin, residual_N, moving, stroke, vmax):
            yield {"wavelength_m": lam}
    elif effect is fx.ReversalTransient:
        for length in np.geomspace(breakaway_m / 10, max(stroke / 5, breakaway_m), 14):
            yield {"length_m": float(length)}
    elif effect is fx.Drift:
        for tau in np.geomspace(duration / 50, 2 * duration, 10):
            yield {"tau_s": float(tau)}
    else:
        yield {}


def ripple_wavelengths(
    kin: Kinematics, residual_N: FloatArray, moving: BoolArray, stroke: float, vmax: float
) -> list[float]:
    """Wavelengths where the residual's projection on sin/cos(2 pi x / lambda) peaks,
    refined on a fine grid around the three strongest peaks."""
    dt = float(kin.time_s[1] - kin.time_s[0])
    lo = max(4 * vmax * dt, 1e-6)  # at least four samples per period at top speed
    hi = stroke / 3
    if hi <= lo:
        return []
    x = kin.position_m[moving]
    r = residual_N[moving] - np.mean(residual_N[moving])
    step = max(1, x.size // 20000)  # the scan needs no more samples than this
    x, r = x[::step], r[::step]
    grid = np.geomspace(lo, hi, 600)
    power = np.array([abs(np.dot(r, np.exp(-2j * np.pi * x / lam))) for lam in grid])
    peaks = [i for i in np.argsort(power)[::-1] if 0 < i < grid.size - 1][:3]
    ratio = grid[1] / grid[0]
    out: list[float] = []
    for i in peaks:
        out.extend(float(v) for v in np.geomspace(grid[i] / ratio, grid[i] * ratio, 7))
    return out
