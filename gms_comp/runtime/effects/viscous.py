"""``viscous``: dF = c v, c >= 0 (viscous friction dissipates)."""

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
class Viscous(Effect):
    """Viscous friction ``c_Ns_per_m`` times the velocity."""

    name: ClassVar[str] = "viscous"
    c_Ns_per_m: float = field(metadata=in_range(0.0, 1e7))

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        """The velocity."""
        return ctx.velocity_m_s[:, None]

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        """The effect with slope ``coefficients[0]``."""
        return cls(float(coefficients[0]))

    def coefficients(self) -> FloatArray:
        """``[c]``."""
        return np.array([self.c_Ns_per_m])
