"""``stribeck``: element limits scaled by 1 + (r - 1) exp(-(|v|/v_s)^2), r > 1: friction
falls from break-away towards sliding (a rise is the baseline's slip level C_v)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.config import positive
from gms_comp.runtime.effects.base import Effect, Shape, top_speed
from gms_comp.runtime.effects.leftover import Leftover
from gms_comp.runtime.effects.path import Context


@dataclass(frozen=True)
class Stribeck(Effect):
    """Stribeck ratio ``ratio`` (break-away over sliding level) and speed ``v_s_m_per_s``."""

    name: ClassVar[str] = "stribeck"
    SHAPE: ClassVar[tuple[str, ...]] = ("v_s_m_per_s",)
    COEFFICIENT_LOWER: ClassVar[float] = 0.0  # ratio - 1 >= 0
    ratio: float = field(metadata=positive(100.0))
    v_s_m_per_s: float = field(metadata=positive(10.0))

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        """The GMS force times the Stribeck bump."""
        u = ctx.velocity_m_s / shape["v_s_m_per_s"]
        return (ctx.gms_force_N * np.exp(-(u * u)))[:, None]

    @classmethod
    def departure(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        """The fall itself, the GMS force times 1 - the bump: at slow speeds the bump
        is the GMS force the baseline's limits already carry."""
        u = ctx.velocity_m_s / shape["v_s_m_per_s"]
        return ctx.gms_force_N * -np.expm1(-(u * u))

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        """The effect with ``ratio - 1 = coefficients[0]``."""
        return cls(1.0 + float(coefficients[0]), shape["v_s_m_per_s"])

    def coefficients(self) -> FloatArray:
        """``[ratio - 1]``."""
        return np.array([self.ratio - 1.0])

    @classmethod
    def shape_grid(cls, ctx: Context, left: Leftover, presliding_m: float) -> list[Shape]:
        """Stribeck speeds from 1/200 to 1/2 of the top speed."""
        vmax = top_speed(ctx)
        return [{"v_s_m_per_s": float(v)} for v in np.geomspace(vmax / 200, vmax / 2, 10)]

    @classmethod
    def shape_bounds(cls, ctx: Context, presliding_m: float) -> dict[str, tuple[float, float]]:
        """v_s within 1/1000 and 1/2 of the top speed: the ratio is break-away over the
        sliding level, so the trace must reach sliding (at half the top speed the bump is
        2 % at the top speed, the grid's top). A bump still 37 % high at the top speed
        (v_s = 36 mm/s, the bound before) was ranked above an independent trace's viscous
        term while its top speeds were held out; with them trained on, the two bounds
        give the same names there (prepare.TRAIN_TOP_SHARE)."""
        vmax = top_speed(ctx)
        return {"v_s_m_per_s": (vmax / 1000, vmax / 2)}
