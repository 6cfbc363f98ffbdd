"""``stribeck``: element limits scaled by 1 + (r - 1) exp(-(|v|/v_s)^2), r > 1: friction
falls from break-away towards sliding (a rise is the baseline's slip level C_v)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.config import positive
from gms_comp.runtime.effects.base import Effect
from gms_comp.runtime.effects.path import Context


@dataclass(frozen=True)
class Stribeck(Effect):
    """Stribeck ratio ``ratio`` (break-away over sliding level) and speed ``v_s_m_per_s``."""

    name: ClassVar[str] = "stribeck"
    SHAPE: ClassVar[tuple[str, ...]] = ("v_s_m_per_s",)
    ratio: float = field(metadata=positive(100.0))
    v_s_m_per_s: float = field(metadata=positive(10.0))

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        """The GMS force times the Stribeck bump."""
        u = ctx.velocity_m_s / shape["v_s_m_per_s"]
        return (ctx.gms_force_N * np.exp(-(u * u)))[:, None]

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        """The effect with ``ratio - 1 = coefficients[0]``."""
        return cls(1.0 + float(coefficients[0]), shape["v_s_m_per_s"])

    def coefficients(self) -> FloatArray:
        """``[ratio - 1]``."""
        return np.array([self.ratio - 1.0])
