"""The diagnosis policy of ``dwell_time``: gamma >= 0; tau from a tenth of the median
standstill to the trace's length; the windows computed at the fitted gain; judged where it
acts, at the starts after a standstill, and reported as the gain after the median one."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.measured.policies.base import Policy, Shape, duration
from gms_comp.measured.policies.leftover import Leftover
from gms_comp.runtime import effects as fx

# The time constants considered (s): far below a servo cycle or above a trace's length a
# dwell gain cannot be told from a constant one.
TAU_RANGE_S = (1e-4, 1e2)
# The forms at a turn (kept_through_turns), each fitted from its own starts.
FITTED_FORMS = (0.0, 1.0)
# The gains at which the column's windows are computed (0.5 % to 1.5 x the limits).
REACH_RANGE = (5e-3, 1.5)


class DwellTimePolicy(Policy):
    """The raised GMS's extra force at the gain ``reach``, over ``reach``."""

    effect: ClassVar[type[fx.Effect]] = fx.DwellTime
    coefficient_lower: ClassVar[float] = 0.0
    set_by_size: ClassVar[tuple[str, ...]] = ("reach",)
    discrete: ClassVar[tuple[str, ...]] = ("kept_through_turns",)
    at_events: ClassVar[bool] = True
    size_parameter: ClassVar[str] = "gamma"
    limit_figure: ClassVar[str] = "gain_after_median_dwell"
    to_see_smaller: ClassVar[str] = (
        "more starts after standstills, of lengths spread over a decade or more"
    )

    @classmethod
    def size(cls, effect: fx.Effect) -> float:
        """gamma (at a given tau, the gain after any standstill is proportional to it)."""
        assert isinstance(effect, fx.DwellTime)
        return effect.gamma

    @classmethod
    def consistent_shape(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Shape:
        """The windows computed at the fitted gain (``reach = gamma``, within its range):
        a column computed at one gain and scaled to another is a different force."""
        return {**shape, "reach": float(np.clip(coefficients[0], *REACH_RANGE))}

    @classmethod
    def in_context(cls, effect: fx.Effect, ctx: fx.Context) -> dict[str, float]:
        """The median standstill before the starts along ``ctx`` and the break-away gain
        after it, gamma ln(1 + t/tau): what a trace's starts determine ((gamma, tau)
        pairs with the same gains at its dwells fit alike)."""
        assert isinstance(effect, fx.DwellTime)
        dwells = ctx.dwell_s[ctx.starts()]
        dwells = dwells[dwells > 0.0]
        if dwells.size == 0:
            return {}
        median = float(np.median(dwells))
        return {
            "median_dwell_s": median,
            "gain_after_median_dwell": effect.gamma * math.log1p(median / effect.tau_s),
        }

    @classmethod
    def ridge(
        cls, figures: Mapping[str, float], bounds: Mapping[str, tuple[float, float]],
        ctx: fx.Context, presliding_m: float,
    ) -> dict[str, tuple[float, float]]:  # fmt: skip
        """gamma and tau along the gain after the median standstill the trace determines
        (within its interval): tau anywhere in its bounds, gamma what gives that gain."""
        gain = bounds.get("gain_after_median_dwell")
        if gain is None or "median_dwell_s" not in figures:
            return {}
        median = figures["median_dwell_s"]
        lo, hi = cls.shape_bounds(ctx, presliding_m)["tau_s"]
        return {
            "tau_s": (lo, hi),
            "gamma": (gain[0] / math.log1p(median / lo), gain[1] / math.log1p(median / hi)),
        }

    @classmethod
    def relative_size(cls, effect: fx.Effect, ctx: fx.Context) -> float | None:
        """The break-away gain after the median standstill (:meth:`in_context`)."""
        return cls.in_context(effect, ctx).get("gain_after_median_dwell", 0.0)

    @classmethod
    def shape_grid(cls, ctx: fx.Context, left: Leftover, presliding_m: float) -> list[Shape]:
        """tau over the decades from :func:`shortest_tau` to the trace's length; gains
        3-30 %; both forms at a turn."""
        lo, hi = cls.shape_bounds(ctx, presliding_m)["tau_s"]
        return [
            {"tau_s": float(tau), "reach": reach, "kept_through_turns": keep}
            for tau in np.geomspace(lo, max(min(hi, duration(ctx)), 2 * lo), 9)
            for reach in (0.03, 0.1, 0.3)
            for keep in FITTED_FORMS
        ]

    @classmethod
    def shape_bounds(cls, ctx: fx.Context, presliding_m: float) -> dict[str, tuple[float, float]]:
        """tau from :func:`shortest_tau` to ``TAU_RANGE_S``'s top, the gain in
        ``REACH_RANGE``."""
        return {"tau_s": (shortest_tau(ctx), TAU_RANGE_S[1]), "reach": REACH_RANGE}


def shortest_tau(ctx: fx.Context) -> float:
    """A tenth of the median standstill before the starts: far below every dwell, ln(1 +
    t_d / tau) hardly changes with the dwell, and such a column takes up the baseline's
    mismatch at the starts."""
    dwells = ctx.dwell_s[ctx.starts()]
    dwells = dwells[dwells > 0.0]
    if dwells.size == 0:
        return TAU_RANGE_S[0]
    return float(np.clip(0.1 * np.median(dwells), *TAU_RANGE_S))
