"""The interface of a diagnosis policy: how the diagnosis searches, judges and reports
one catalogue effect (:class:`Policy`).

The runtime's effect (:mod:`gms_comp.runtime.effects`) holds what the compensator runs:
its parameters, its form, its design columns. Everything the diagnosis alone needs to fit
it from a trace lives in its policy: the bound of its fitted coefficients (the
parameters' physical meaning), the shapes it searches and their bounds, how its shape
follows its size, where it acts, what it can trade against (the slip level, the
elements placed before it is known), the size its detection limit is stated in and what
to record to see a smaller one. The selection, the refit and the level search read these
fields; none of them names an effect.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import ClassVar

import numpy as np

from gms_comp.arrays import BoolArray, FloatArray
from gms_comp.measured.policies.leftover import Leftover
from gms_comp.runtime import effects as fx

Shape = dict[str, float]


class Policy:
    """How the diagnosis fits one catalogue effect (class attributes and classmethods,
    like the effect itself; see the module docstring)."""

    effect: ClassVar[type[fx.Effect]]
    # Lower bound of every fitted coefficient (the parameters' physical meaning).
    coefficient_lower: ClassVar[float] = -math.inf
    # Whether its basis reads the GMS (its force or its elements); if not, its columns
    # are the motion's alone and are kept across baselines.
    basis_reads_gms: ClassVar[bool] = True
    # Whether :meth:`shape_grid` reads what the design leaves (else it gets an empty one).
    reads_leftover: ClassVar[bool] = False
    # Shape keys that :meth:`consistent_shape` sets from the fitted size (not searched).
    set_by_size: ClassVar[tuple[str, ...]] = ()
    # Shape keys that take a few values (a filter's order, a form): each value's best is
    # refined on its own, never stepped.
    discrete: ClassVar[tuple[str, ...]] = ()
    # The force kinds it is a candidate for (a drive force holds its mass in the baseline;
    # only a drive command can lead the force).
    force_kinds: ClassVar[tuple[str, ...]] = ("friction", "drive")
    # What it can trade against, and so what it is judged against:
    # - the elements: the blind baseline's elements, placed before it was known, took part
    #   of it; the refit places them again on the force without it;
    elements_take_part: ClassVar[bool] = False
    # - the slip level: this shape key is searched together with C_v and v_t in the refit
    #   (the lowest ``level_rank`` of the kept effects is), and a kept effect of this kind
    #   is judged against the model refitted without it beside another effect;
    level_shape: ClassVar[str | None] = None
    level_rank: ClassVar[int] = 0
    # - a slip level the blind baseline did not find: scored with the level free in the
    #   first rounds, and judged against the model refitted without it when kept there or
    #   after another effect;
    free_level: ClassVar[bool] = False
    # - a force of the speed or of the direction (one trace's narrow speed bands cannot
    #   tell these apart: coverage.speed_direction_confound).
    speed_or_direction: ClassVar[bool] = False
    # It acts at a few events (a dwell gain at the starts): its shape is costed on every
    # row in the refit.
    at_events: ClassVar[bool] = False
    # The parameter its detection limit is stated in, and what to record to see a smaller
    # one.
    size_parameter: ClassVar[str] = ""
    to_see_smaller: ClassVar[str] = ""
    # The figure its detection limit is told in (a parameter or an in-context figure;
    # empty: the size parameter).
    limit_figure: ClassVar[str] = ""

    @classmethod
    def shape_grid(cls, ctx: fx.Context, left: Leftover, presliding_m: float) -> list[Shape]:
        """Candidate shapes the diagnosis tries (``left``: what the design leaves)."""
        return [{}]

    @classmethod
    def shape_bounds(cls, ctx: fx.Context, presliding_m: float) -> dict[str, tuple[float, float]]:
        """The range of each shape parameter the local search may reach."""
        return {}

    @classmethod
    def shape_steps(cls, ctx: fx.Context) -> tuple[float, ...] | None:
        """Relative steps, shrinking, of the local search after the grid (None: the
        diagnosis's own)."""
        return None

    @classmethod
    def consistent_shape(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Shape:
        """The shape that agrees with the fitted ``coefficients`` (``shape`` itself where
        size and shape are independent)."""
        return dict(shape)

    @classmethod
    def departure(cls, ctx: fx.Context, shape: Mapping[str, float]) -> FloatArray | None:
        """Where it departs from what the baseline carries, as values whose large rows
        are where it acts (None: its basis)."""
        return None

    @classmethod
    def told_apart(cls, ctxs: Sequence[fx.Context]) -> list[BoolArray] | None:
        """The rows along each of ``ctxs`` whose motion tells it from the effects it could
        stand in for, where its gain must show (None: every row)."""
        return None

    @classmethod
    def in_context(cls, effect: fx.Effect, ctx: fx.Context) -> dict[str, float]:
        """What its parameters come to along ``ctx``, where a trace determines that
        better than the parameters themselves (none by default)."""
        return {}

    @classmethod
    def ridge(
        cls, figures: Mapping[str, float], bounds: Mapping[str, tuple[float, float]],
        ctx: fx.Context, presliding_m: float,
    ) -> dict[str, tuple[float, float]]:  # fmt: skip
        """The range of the parameters a trace determines only together, along what it
        does determine (``figures``: the fitted parameters and in-context figures,
        ``bounds``: their intervals); none by default."""
        return {}

    @classmethod
    def relative_size(cls, effect: fx.Effect, ctx: fx.Context) -> float | None:
        """Its size along ``ctx`` as a fraction of the friction it scales, where that is
        how it is judged worth keeping (None: by the force it changes)."""
        return None

    @classmethod
    def detection_shapes(cls, ctx: fx.Context, presliding_m: float, count: int) -> list[Shape]:
        """At most ``count`` shapes spread over its grid (discrete keys at their first
        value), where its detection limit is worked out."""
        grid = cls.shape_grid(ctx, Leftover.empty(), presliding_m)
        if not grid:
            return []
        first = {k: grid[0][k] for k in cls.discrete if k in grid[0]}
        grid = [s for s in grid if all(s[k] == v for k, v in first.items())]
        picks = np.unique(np.linspace(0, len(grid) - 1, count).round().astype(int))
        return [grid[i] for i in picks]

    @classmethod
    def size(cls, effect: fx.Effect) -> float:
        """Its size, larger for a larger effect (its ``size_parameter``'s magnitude)."""
        return abs(float(effect.parameters()[cls.size_parameter]))


def top_speed(ctx: fx.Context) -> float:
    """The largest speed along ``ctx`` (m/s), at least a tiny positive number."""
    return max(float(np.max(np.abs(ctx.velocity_m_s))), 1e-12)


def duration(ctx: fx.Context) -> float:
    """The time ``ctx`` spans (s), at least one sample time."""
    return max(float(ctx.time_s[-1] - ctx.time_s[0]), ctx.sample_time_s)


def stroke(ctx: fx.Context) -> float:
    """The range of positions along ``ctx`` (m)."""
    return float(np.ptp(ctx.position_m))
