"""``direction_asymmetry`` (beyond the spec's catalogue): viscous friction that differs by
direction, dF = c_diff |v| / 2, so the slope is c + c_diff/2 moving forward and
c - c_diff/2 moving back (EMPS: a fatigued screw, Janot et al. 2019, section 4.2)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from gms_comp.arrays import BoolArray, FloatArray
from gms_comp.config import in_range
from gms_comp.runtime.effects.base import Effect
from gms_comp.runtime.effects.path import Context


@dataclass(frozen=True)
class DirectionAsymmetry(Effect):
    """Half the difference ``c_diff_Ns_per_m`` of the viscous slopes by direction."""

    name: ClassVar[str] = "direction_asymmetry"
    BASIS_READS_GMS: ClassVar[bool] = False
    c_diff_Ns_per_m: float = field(metadata=in_range(-1e7, 1e7))

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        """Half the speed."""
        return 0.5 * np.abs(ctx.velocity_m_s)[:, None]

    @classmethod
    def told_apart(cls, ctxs: Sequence[Context]) -> list[BoolArray]:
        """The moving rows at speeds the parts reach both ways: where one direction alone
        moves at a speed, half its speed is also a level that falls or rises with the
        speed there (on stribeck-159 of an independent generator, one move of the trace's
        35 mm/s forward, back at 2.1 mm/s at most: half the speed took a Stribeck fall
        at that move as well as Stribeck did, held out within 0.04 %). None on a trace
        that moves one way only."""
        moving = [(c.velocity_m_s, c.moving != 0.0) for c in ctxs]
        both = min(
            max(float(np.max(sign * v[m], initial=0.0)) for v, m in moving) for sign in (1.0, -1.0)
        )
        return [m & (np.abs(v) <= both) & (both > 0.0) for v, m in moving]

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        """The effect with slope difference ``coefficients[0]``."""
        return cls(float(coefficients[0]))

    def coefficients(self) -> FloatArray:
        """``[c_diff]``."""
        return np.array([self.c_diff_Ns_per_m])
