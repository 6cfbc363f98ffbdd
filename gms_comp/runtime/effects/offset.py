"""``offset``: dF = F0 (gravity on an inclined axis, cable drag, sensor offset)."""

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
class Offset(Effect):
    """A constant force ``offset_N`` of either sign."""

    name: ClassVar[str] = "offset"
    offset_N: float = field(metadata=in_range(-1e6, 1e6))

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        """A column of ones."""
        return np.ones((len(ctx.time_s), 1))

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        """The offset ``coefficients[0]``."""
        return cls(float(coefficients[0]))

    def coefficients(self) -> FloatArray:
        """``[F0]``."""
        return np.array([self.offset_N])
