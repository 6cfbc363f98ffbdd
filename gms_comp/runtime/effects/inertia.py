"""``inertia``: dF = m a, m >= 0 (the force is measured at the drive)."""

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
class Inertia(Effect):
    """The moving mass ``mass_kg`` times the acceleration."""

    name: ClassVar[str] = "inertia"
    # the acceleration feedforward already supplies the inertial force
    measurement_only: ClassVar[bool] = True
    mass_kg: float = field(metadata=in_range(0.0, 1e5))

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        """The acceleration."""
        return ctx.acceleration_m_s2[:, None]

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        """The mass ``coefficients[0]``."""
        return cls(float(coefficients[0]))

    def coefficients(self) -> FloatArray:
        """``[m]``."""
        return np.array([self.mass_kg])
