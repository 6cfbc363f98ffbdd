"""``sensor_lowpass``: the measured force is a Butterworth low-pass of order n, cut-off
f_c, of the true force (a filter of the measurement chain, not of the contact)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from scipy import signal

from gms_comp.arrays import FloatArray
from gms_comp.config import in_range, positive
from gms_comp.runtime.effects.base import FilterEffect, Shape
from gms_comp.runtime.effects.leftover import Leftover
from gms_comp.runtime.effects.path import Context

# Butterworth orders the diagnosis tries (the catalogue's "order n"; sensor front ends are
# 1st to 4th order).
ORDERS = (1, 2, 3, 4)


@dataclass(frozen=True)
class SensorLowpass(FilterEffect):
    """The sensor reports a causal Butterworth low-pass of the true force."""

    name: ClassVar[str] = "sensor_lowpass"
    measurement_only: ClassVar[bool] = True
    cutoff_Hz: float = field(metadata=positive(1e6))
    order: int = field(metadata=in_range(1, 8))

    @classmethod
    def from_shape(cls, shape: Mapping[str, float]) -> FilterEffect:
        """The filter with ``cutoff_Hz`` and ``order``."""
        return cls(float(shape["cutoff_Hz"]), int(shape["order"]))

    def filter(self, sample_time_s: float) -> tuple[FloatArray, FloatArray]:
        """The Butterworth coefficients (cut-off at most 0.99 Nyquist)."""
        nyquist_Hz = 0.5 / sample_time_s
        b, a = signal.butter(self.order, min(self.cutoff_Hz / nyquist_Hz, 0.99))
        return np.asarray(b), np.asarray(a)

    def parameters(self) -> dict[str, float]:
        """``cutoff_Hz`` and the integer ``order``."""
        return {"cutoff_Hz": float(self.cutoff_Hz), "order": int(self.order)}

    @classmethod
    def shape_grid(cls, ctx: Context, left: Leftover, presliding_m: float) -> list[Shape]:
        """Cut-offs from 1/1000 to 1/2 of Nyquist (a force sensor's few Hz at a 5 kHz
        sample rate included), orders 1 to 4."""
        nyquist = 0.5 / ctx.sample_time_s
        return [
            {"cutoff_Hz": float(fc), "order": float(order)}
            for fc in np.geomspace(nyquist / 1000, nyquist / 2, 14)
            for order in ORDERS
        ]

    @classmethod
    def shape_bounds(cls, ctx: Context, presliding_m: float) -> dict[str, tuple[float, float]]:
        """Cut-offs within 1/3000 and 0.99 of Nyquist (the order is not searched)."""
        nyquist = 0.5 / ctx.sample_time_s
        return {"cutoff_Hz": (nyquist / 3000, 0.99 * nyquist)}
