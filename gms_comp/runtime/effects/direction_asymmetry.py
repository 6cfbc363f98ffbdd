"""``direction_asymmetry`` (beyond the spec's catalogue): viscous friction that differs by
direction, dF = c_diff |v| / 2, so the slope is c + c_diff/2 moving forward and
c - c_diff/2 moving back (EMPS: a fatigued screw, Janot et al. 2019, section 4.2)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.config import in_range
from gms_comp.runtime.effects.base import Effect
from gms_comp.runtime.effects.path import Context


@dataclass(frozen=True)
class DirectionAsymmetry(Effect):
    """Half the difference ``c_diff_Ns_per_m`` of the viscous slopes by direction."""

    name: ClassVar[str] = "direction_asymmetry"
    c_diff_Ns_per_m: float = field(metadata=in_range(-1e7, 1e7))

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        """Half the speed."""
        return 0.5 * np.abs(ctx.velocity_m_s)[:, None]

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        """The effect with slope difference ``coefficients[0]``."""
        return cls(float(coefficients[0]))

    def coefficients(self) -> FloatArray:
        """``[c_diff]``."""
        return np.array([self.c_diff_Ns_per_m])
