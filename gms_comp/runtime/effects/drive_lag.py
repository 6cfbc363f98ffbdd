"""``drive_lag`` (beyond the spec's catalogue, drive-force traces only): the axis force
follows the drive command with a first-order lag (current loop, motor inductance), so the
recorded command leads the force: command = force + lag_s dforce/dt."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.config import in_range
from gms_comp.runtime.effects.base import FilterEffect


@dataclass(frozen=True)
class DriveLag(FilterEffect):
    """The command leads the force by the first-order lag ``lag_s``."""

    name: ClassVar[str] = "drive_lag"
    measurement_only: ClassVar[bool] = True
    lag_s: float = field(metadata=in_range(0.0, 1.0))

    @classmethod
    def from_shape(cls, shape: Mapping[str, float]) -> FilterEffect:
        """The lag ``lag_s``."""
        return cls(float(shape["lag_s"]))

    def filter(self, sample_time_s: float) -> tuple[FloatArray, FloatArray]:
        """force + lag dforce/dt by a backward difference."""
        r = self.lag_s / sample_time_s
        return np.array([1.0 + r, -r]), np.array([1.0])
