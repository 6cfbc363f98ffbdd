"""``dwell_time``: break-away limits after a standstill of duration t_d scaled by
1 + gamma ln(1 + t_d/tau), gamma >= 0; the gain is lost once the elements slip again."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.runtime.effects.base import Effect, Shape, duration
from gms_comp.runtime.effects.path import Context

# The time constants the diagnosis considers (s): far below a servo cycle or above a
# trace's length a dwell gain cannot be told from a constant one.
TAU_RANGE_S = (1e-4, 1e2)


@dataclass(frozen=True)
class DwellTime(Effect):
    """Break-away force raised by 1 + gamma ln(1 + t_d/tau) until ``breakaway_m`` of
    travel after the standstill (then the elements slip and the gain is gone)."""

    name: ClassVar[str] = "dwell_time"
    SHAPE: ClassVar[tuple[str, ...]] = ("tau_s", "breakaway_m")
    COEFFICIENT_LOWER: ClassVar[float] = 0.0
    gamma: float
    tau_s: float
    breakaway_m: float

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        """The GMS force times ln(1 + t_d/tau) inside the break-away window."""
        window = ctx.moving * (ctx.distance_since_start_m < shape["breakaway_m"])
        gain = np.log1p(ctx.dwell_s / max(shape["tau_s"], TAU_RANGE_S[0]))
        return (ctx.gms_force_N * gain * window)[:, None]

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        """The effect with gain ``gamma = coefficients[0]``."""
        return cls(float(coefficients[0]), shape["tau_s"], shape["breakaway_m"])

    def coefficients(self) -> FloatArray:
        """``[gamma]``."""
        return np.array([self.gamma])

    @classmethod
    def shape_grid(cls, ctx: Context, residual_N: FloatArray, presliding_m: float) -> list[Shape]:
        """tau over five decades from 1 ms, windows of 0.5-2 presliding lengths."""
        top = min(TAU_RANGE_S[1], duration(ctx))
        return [
            {"tau_s": float(tau), "breakaway_m": scale * presliding_m}
            for tau in np.geomspace(1e-3, max(top, 2e-3), 9)
            for scale in (0.5, 1.0, 2.0)
        ]

    @classmethod
    def shape_bounds(cls, ctx: Context, presliding_m: float) -> dict[str, tuple[float, float]]:
        """tau in ``TAU_RANGE_S``; the window within 0.1-10 presliding lengths."""
        return {"tau_s": TAU_RANGE_S, "breakaway_m": (0.1 * presliding_m, 10 * presliding_m)}
