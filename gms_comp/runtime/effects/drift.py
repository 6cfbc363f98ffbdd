"""``drift``: friction scaled by 1 + kappa (1 - exp(-t/tau)) (warm-up, run-in), kappa > -1
(the friction keeps its sign)."""

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
class Drift(Effect):
    """Relative change ``kappa`` of the friction over the time constant ``tau_s``."""

    name: ClassVar[str] = "drift"
    SHAPE: ClassVar[tuple[str, ...]] = ("tau_s",)
    kappa: float = field(metadata=in_range(-1.0, 100.0))
    tau_s: float = field(metadata=positive(1e7))

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        """The GMS force times 1 - exp(-t/tau)."""
        return (ctx.gms_force_N * -np.expm1(-ctx.elapsed_s / shape["tau_s"]))[:, None]

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        """The effect with ``kappa = coefficients[0]``."""
        return cls(float(coefficients[0]), shape["tau_s"])

    def coefficients(self) -> FloatArray:
        """``[kappa]``."""
        return np.array([self.kappa])
