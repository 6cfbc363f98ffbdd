"""The diagnosis policy of ``stribeck``: ratio > 1, v_s within the trace's speeds; it
trades against the slip level (C_v over v_t) the blind baseline fitted alone."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.measured.policies.base import Policy, Shape, top_speed
from gms_comp.measured.policies.leftover import Leftover
from gms_comp.runtime import effects as fx


class StribeckPolicy(Policy):
    """The GMS force times the Stribeck bump."""

    effect: ClassVar[type[fx.Effect]] = fx.Stribeck
    coefficient_lower: ClassVar[float] = 0.0  # ratio - 1 >= 0
    level_shape: ClassVar[str | None] = "v_s_m_per_s"
    level_rank: ClassVar[int] = 1
    free_level: ClassVar[bool] = True
    speed_or_direction: ClassVar[bool] = True
    size_parameter: ClassVar[str] = "ratio"
    to_see_smaller: ClassVar[str] = "moves through the speeds around v_s, up to several times it"

    @classmethod
    def size(cls, effect: fx.Effect) -> float:
        """ratio - 1: the fall's height relative to the sliding level."""
        assert isinstance(effect, fx.Stribeck)
        return effect.ratio - 1.0

    @classmethod
    def departure(cls, ctx: fx.Context, shape: Mapping[str, float]) -> FloatArray:
        """The fall itself, the GMS force times 1 - the bump: at slow speeds the bump is
        the GMS force the baseline's limits already carry."""
        u = ctx.velocity_m_s / shape["v_s_m_per_s"]
        return ctx.gms_force_N * -np.expm1(-(u * u))

    @classmethod
    def shape_grid(cls, ctx: fx.Context, left: Leftover, presliding_m: float) -> list[Shape]:
        """Stribeck speeds from 1/200 to 1/2 of the top speed."""
        vmax = top_speed(ctx)
        return [{"v_s_m_per_s": float(v)} for v in np.geomspace(vmax / 200, vmax / 2, 10)]

    @classmethod
    def shape_bounds(cls, ctx: fx.Context, presliding_m: float) -> dict[str, tuple[float, float]]:
        """v_s within 1/1000 and 1/2 of the top speed: the ratio is break-away over the
        sliding level, so the trace must reach sliding (at half the top speed the bump is
        2 % at the top speed)."""
        vmax = top_speed(ctx)
        return {"v_s_m_per_s": (vmax / 1000, vmax / 2)}
