"""``dwell_time``: break-away limits after a standstill of duration t_d scaled by
1 + gamma ln(1 + t_d/tau), gamma >= 0; the gain is lost once the elements slip again.

A raised limit does not raise the force at once: an element that has come to rest at its
limit x_i stretches on with its stiffness k_i for another gamma L x_i (L = ln(1 + t_d/tau))
before it slips back to its old limit. Over the elements the extra force after a travel s
from the rest position is s times the stiffness of the elements not yet slipped; for
limits spread exponentially about a length x (stiffness F/x in all, F the GMS force) it is

    gamma F (s / w) exp(-s / (w L)),  w = gamma x,

a ramp that peaks at gamma L F / e after a travel w L and is gone a few w L later. With
the shape (tau, w) fixed it is linear in gamma, a column of the design."""

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
# Beyond this many decay lengths the ramp is taken as gone (6 e^-6 is 4 % of its peak):
# its support, where the diagnosis judges it, stays where it acts.
MAX_DECAYS = 6.0


@dataclass(frozen=True)
class DwellTime(Effect):
    """Break-away limits raised by 1 + gamma ln(1 + t_d/tau) after a standstill;
    ``breakaway_m`` is w = gamma x, the extra stretch of the elements per unit of the
    logarithm (so the raised force is lost over a few ``breakaway_m`` ln(1 + t_d/tau))."""

    name: ClassVar[str] = "dwell_time"
    SHAPE: ClassVar[tuple[str, ...]] = ("tau_s", "breakaway_m")
    COEFFICIENT_LOWER: ClassVar[float] = 0.0
    gamma: float
    tau_s: float
    breakaway_m: float

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        """F (s / w) exp(-s / (w L)) after a standstill (module docstring), 0 at rest."""
        w = shape["breakaway_m"]
        gain = np.log1p(ctx.dwell_s / max(shape["tau_s"], TAU_RANGE_S[0]))
        s = ctx.distance_since_start_m
        decay = np.zeros_like(s)
        raised = (
            (gain > 0.0)
            & (ctx.resting == 0.0)
            & (s < MAX_DECAYS * w * gain)
            & (ctx.gms_force_N * ctx.direction > 0.0)
        )
        decay[raised] = np.exp(-s[raised] / (w * gain[raised]))
        return (ctx.gms_force_N * (s / w) * decay)[:, None]

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        """The effect with gain ``gamma = coefficients[0]``."""
        return cls(float(coefficients[0]), shape["tau_s"], shape["breakaway_m"])

    def coefficients(self) -> FloatArray:
        """``[gamma]``."""
        return np.array([self.gamma])

    @classmethod
    def shape_grid(cls, ctx: Context, residual_N: FloatArray, presliding_m: float) -> list[Shape]:
        """tau over five decades from 1 ms; w from 1 % to 30 % of the presliding length
        (gamma 0.01-0.3 of limits spread over about that length)."""
        top = min(TAU_RANGE_S[1], duration(ctx))
        return [
            {"tau_s": float(tau), "breakaway_m": scale * presliding_m}
            for tau in np.geomspace(1e-3, max(top, 2e-3), 9)
            for scale in (0.01, 0.03, 0.1, 0.3)
        ]

    @classmethod
    def shape_bounds(cls, ctx: Context, presliding_m: float) -> dict[str, tuple[float, float]]:
        """tau in ``TAU_RANGE_S``; w within 1 % to 3 presliding lengths (below, the ramp
        is over within an encoder step or two of a start, where filter and quantisation
        make their own)."""
        return {"tau_s": TAU_RANGE_S, "breakaway_m": (1e-2 * presliding_m, 3 * presliding_m)}
