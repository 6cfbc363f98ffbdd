"""The diagnosis policy of ``reversal_transient``: A > 0 over lengths from a fraction of
the presliding length to the stroke; the blind elements take part of it."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from gms_comp.measured.policies.base import Policy, Shape, stroke
from gms_comp.measured.policies.leftover import Leftover
from gms_comp.runtime import effects as fx


class ReversalTransientPolicy(Policy):
    """The direction times a decay with the distance since the reversal."""

    effect: ClassVar[type[fx.Effect]] = fx.ReversalTransient
    coefficient_lower: ClassVar[float] = 0.0
    basis_reads_gms: ClassVar[bool] = False
    elements_take_part: ClassVar[bool] = True
    size_parameter: ClassVar[str] = "amplitude_N"
    to_see_smaller: ClassVar[str] = "more reversals, each followed by a long enough stroke"

    @classmethod
    def shape_grid(cls, ctx: fx.Context, left: Leftover, presliding_m: float) -> list[Shape]:
        """Lengths from a tenth of the presliding length to a fifth of the stroke."""
        hi = max(stroke(ctx) / 5, presliding_m)
        return [{"length_m": float(s)} for s in np.geomspace(presliding_m / 10, hi, 14)]

    @classmethod
    def shape_bounds(cls, ctx: fx.Context, presliding_m: float) -> dict[str, tuple[float, float]]:
        """Lengths within 1/20 of the presliding length and the stroke."""
        return {"length_m": (presliding_m / 20, max(stroke(ctx), presliding_m))}
