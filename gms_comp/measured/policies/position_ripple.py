"""The diagnosis policy of ``position_ripple``: wavelengths found by what their sin/cos
pair adds to the design, from four samples per period at top speed to the stroke over
``MIN_PERIODS``; the blind elements take part of it."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.measured.policies.base import Policy, Shape, stroke, top_speed
from gms_comp.measured.policies.leftover import Leftover
from gms_comp.runtime import effects as fx

# Wavelengths scanned for what their sin/cos pair adds to the design, CHUNK at a time.
SCAN_POINTS = 600
CHUNK = 50
# Around each of the three strongest scan points, FINE_STEPS wavelengths per scan step on
# either side; then REFINED_STEPS shrinking steps of the local search (shape_steps).
FINE_STEPS = 3
REFINED_STEPS = 4
# The fewest periods over the stroke fitted (a 4.57 mm ripple on a 5.94 mm stroke is 1.3).
MIN_PERIODS = 1.2


class PositionRipplePolicy(Policy):
    """sin and cos of 2 pi x / lambda."""

    effect: ClassVar[type[fx.Effect]] = fx.PositionRipple
    basis_reads_gms: ClassVar[bool] = False
    reads_leftover: ClassVar[bool] = True
    elements_take_part: ClassVar[bool] = True
    size_parameter: ClassVar[str] = "amplitude_N"
    to_see_smaller: ClassVar[str] = "long strokes at a steady speed, crossed many times"

    @classmethod
    def _range(cls, ctx: fx.Context) -> tuple[float, float]:
        # at least four samples per period at top speed, at most the stroke over MIN_PERIODS
        return max(4 * top_speed(ctx) * ctx.sample_time_s, 1e-6), stroke(ctx) / MIN_PERIODS

    @classmethod
    def shape_grid(cls, ctx: fx.Context, left: Leftover, presliding_m: float) -> list[Shape]:
        """Wavelengths whose sin/cos pair lowers most what the design leaves
        (:meth:`~.leftover.Leftover.pair_gains`), refined on a fine grid around the three
        best scan points (the elements absorb part of a ripple, so the residual's own
        spectrum peaks elsewhere)."""
        lo, hi = cls._range(ctx)
        if hi <= lo or left.rows.size == 0:
            return []
        x = ctx.position_m[left.rows]
        grid = np.geomspace(lo, hi, SCAN_POINTS)
        gain = np.concatenate([
            left.pair_gains(*_sin_cos(x, grid[at : at + CHUNK]))
            for at in range(0, grid.size, CHUNK)
        ])  # fmt: skip
        peaks = [i for i in np.argsort(gain)[::-1] if 0 < i < grid.size - 1][:3]
        ratio = grid[1] / grid[0]
        return [
            {"wavelength_m": float(v)}
            for i in peaks
            for v in np.geomspace(grid[i] / ratio, grid[i] * ratio, 2 * FINE_STEPS + 1)
        ]

    @classmethod
    def shape_steps(cls, ctx: fx.Context) -> tuple[float, ...]:
        """From half the fine grid's spacing down by thirds: the phase of a ripple over n
        periods moves 2 pi n times the wavelength's relative error."""
        lo, hi = cls._range(ctx)
        fine = (max(hi, lo) / lo) ** (1.0 / ((SCAN_POINTS - 1) * FINE_STEPS))
        return tuple(float(fine ** (0.5 / 3**k)) for k in range(REFINED_STEPS))

    @classmethod
    def detection_shapes(cls, ctx: fx.Context, presliding_m: float, count: int) -> list[Shape]:
        """Wavelengths spread (in log) over the scanned range, none at its ends."""
        lo, hi = cls._range(ctx)
        if hi <= lo:
            return []
        inner = np.geomspace(lo, hi, count + 2)[1:-1]
        return [{"wavelength_m": float(w)} for w in inner]

    @classmethod
    def shape_bounds(cls, ctx: fx.Context, presliding_m: float) -> dict[str, tuple[float, float]]:
        """The scanned range of wavelengths."""
        return {"wavelength_m": cls._range(ctx)}


def _sin_cos(x: FloatArray, wavelengths: FloatArray) -> tuple[FloatArray, FloatArray]:
    """sin and cos of 2 pi x / lambda, a column per wavelength."""
    arg = (2 * np.pi) * np.outer(x, 1.0 / wavelengths)
    return np.sin(arg), np.cos(arg)
