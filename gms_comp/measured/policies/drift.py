"""The diagnosis policy of ``drift``: kappa > -1 (the friction keeps its sign), tau within
the trace's length; its tau trades against the slip level."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from gms_comp.measured.policies.base import Policy, Shape, duration
from gms_comp.measured.policies.leftover import Leftover
from gms_comp.runtime import effects as fx


class DriftPolicy(Policy):
    """The GMS force times 1 - exp(-t/tau)."""

    effect: ClassVar[type[fx.Effect]] = fx.Drift
    coefficient_lower: ClassVar[float] = -1.0
    # the blind baseline's level is placed on a force that grows over the trace
    level_shape: ClassVar[str | None] = "tau_s"
    level_rank: ClassVar[int] = 2
    size_parameter: ClassVar[str] = "kappa"
    to_see_smaller: ClassVar[str] = "a longer record, the same motion repeated from a cold start"

    @classmethod
    def shape_grid(cls, ctx: fx.Context, left: Leftover, presliding_m: float) -> list[Shape]:
        """Time constants from 1/50 to 2 trace lengths."""
        t = duration(ctx)
        return [{"tau_s": float(tau)} for tau in np.geomspace(t / 50, 2 * t, 10)]

    @classmethod
    def shape_bounds(cls, ctx: fx.Context, presliding_m: float) -> dict[str, tuple[float, float]]:
        """tau within 1/200 and 2 trace lengths (a slower drift is a ramp: its kappa and
        tau trade off and neither means anything)."""
        t = duration(ctx)
        return {"tau_s": (t / 200, 2 * t)}
