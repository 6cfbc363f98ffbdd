"""The diagnosis policy of ``sensor_lowpass``: cut-offs over three decades below the
Nyquist frequency, orders 1-4 (each order's cut-off refined on its own)."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from gms_comp.measured.policies.base import Policy, Shape
from gms_comp.measured.policies.leftover import Leftover
from gms_comp.runtime import effects as fx

# Butterworth orders tried (sensor front ends are 1st to 4th order).
ORDERS = (1, 2, 3, 4)


class SensorLowpassPolicy(Policy):
    """A causal Butterworth low-pass of the whole force."""

    effect: ClassVar[type[fx.Effect]] = fx.SensorLowpass
    discrete: ClassVar[tuple[str, ...]] = ("order",)
    size_parameter: ClassVar[str] = "cutoff_Hz"
    to_see_smaller: ClassVar[str] = "quicker force changes (short reversals at speed)"

    @classmethod
    def size(cls, effect: fx.Effect) -> float:
        """The lag of the filter's step response: a lower cut-off is a larger effect."""
        assert isinstance(effect, fx.SensorLowpass)
        return 1.0 / effect.cutoff_Hz

    @classmethod
    def shape_grid(cls, ctx: fx.Context, left: Leftover, presliding_m: float) -> list[Shape]:
        """Cut-offs from 1/1000 to 1/2 of Nyquist (a force sensor's few Hz at a 5 kHz
        sample rate included), orders 1 to 4."""
        nyquist = 0.5 / ctx.sample_time_s
        return [
            {"cutoff_Hz": float(fc), "order": float(order)}
            for fc in np.geomspace(nyquist / 1000, nyquist / 2, 14)
            for order in ORDERS
        ]

    @classmethod
    def detection_shapes(cls, ctx: fx.Context, presliding_m: float, count: int) -> list[Shape]:
        """A second-order filter (its cut-off is what the limit states)."""
        return [{"cutoff_Hz": 0.25 / ctx.sample_time_s, "order": 2.0}]

    @classmethod
    def shape_bounds(cls, ctx: fx.Context, presliding_m: float) -> dict[str, tuple[float, float]]:
        """Cut-offs within 1/3000 and 0.99 of Nyquist (the order is not searched)."""
        nyquist = 0.5 / ctx.sample_time_s
        return {"cutoff_Hz": (nyquist / 3000, 0.99 * nyquist)}
