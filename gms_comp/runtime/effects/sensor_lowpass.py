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
from gms_comp.runtime.effects.base import FilterEffect


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
