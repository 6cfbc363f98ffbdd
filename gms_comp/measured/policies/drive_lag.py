"""The diagnosis policy of ``drive_lag``: lags of a fraction of a sample time to a few,
drive-force traces only."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from gms_comp.measured.policies.base import Policy, Shape
from gms_comp.measured.policies.leftover import Leftover
from gms_comp.runtime import effects as fx


class DriveLagPolicy(Policy):
    """A first-order lag of the force behind the command."""

    effect: ClassVar[type[fx.Effect]] = fx.DriveLag
    force_kinds: ClassVar[tuple[str, ...]] = ("drive",)
    size_parameter: ClassVar[str] = "lag_s"
    to_see_smaller: ClassVar[str] = "a faster sample rate and quicker force changes"

    @classmethod
    def shape_grid(cls, ctx: fx.Context, left: Leftover, presliding_m: float) -> list[Shape]:
        """Lags from 0.05 to 3 sample times."""
        dt = ctx.sample_time_s
        return [{"lag_s": float(lag)} for lag in np.geomspace(0.05 * dt, 3 * dt, 12)]

    @classmethod
    def detection_shapes(cls, ctx: fx.Context, presliding_m: float, count: int) -> list[Shape]:
        """The lag alone (it is what the limit states)."""
        return [{"lag_s": ctx.sample_time_s}]

    @classmethod
    def shape_bounds(cls, ctx: fx.Context, presliding_m: float) -> dict[str, tuple[float, float]]:
        """Lags within 0.01 and 10 sample times."""
        return {"lag_s": (0.01 * ctx.sample_time_s, 10 * ctx.sample_time_s)}
