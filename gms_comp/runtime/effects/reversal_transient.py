"""``reversal_transient``: dF = A d exp(-s/l), d the direction of motion, s the distance
since the last reversal, A > 0 (an overshoot after every reversal)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.config import in_range, positive
from gms_comp.runtime.effects.base import Effect
from gms_comp.runtime.effects.path import Context


@dataclass(frozen=True)
class ReversalTransient(Effect):
    """Overshoot ``amplitude_N`` decaying over ``length_m`` of travel after a reversal."""

    name: ClassVar[str] = "reversal_transient"
    SHAPE: ClassVar[tuple[str, ...]] = ("length_m",)
    amplitude_N: float = field(metadata=in_range(0.0, 1e6))
    length_m: float = field(metadata=positive(1.0))

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        """The direction times the decay with the distance since the reversal."""
        decay = np.exp(-ctx.distance_since_reversal_m / shape["length_m"])
        return (ctx.direction * decay)[:, None]

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        """The effect with amplitude ``coefficients[0]``."""
        return cls(float(coefficients[0]), shape["length_m"])

    def coefficients(self) -> FloatArray:
        """``[A]``."""
        return np.array([self.amplitude_N])
