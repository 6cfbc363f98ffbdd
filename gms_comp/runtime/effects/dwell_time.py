"""``dwell_time``: break-away limits after a standstill of duration t_d scaled by
1 + gamma ln(1 + t_d/tau), gamma >= 0; the gain is lost once the elements slip again.

The raised limits are the GMS's own, element by element: when the motion resumes after a
standstill, every element sticks where it rested and may stretch up to its limit at the
current speed (level(v) W_i) times g = 1 + G ln(1 + t_d/tau) before it slips to its
sliding force; from then on it is the plain element again. The effect is that force less
the same elements held to g = 1 (the climb from the stick to the sliding level at a start
is the baseline's, not the dwell's): it follows each element's break-away, rising with the
stiffness of the elements not yet slipped and gone once the widest one slips. Only rests
of at least the path's ``REST_HOLD_S`` raise the limits (a slow move below the standstill
speed ends in 'rests' of a sample or two: on dwell_time-106 of an independent generator
they were half the rest ends, set tau's lower bound to 1e-4 s and raised limits where
the truth has no standstill).

Where the move turns back before an element has slipped, the spec's form keeps its gain
until it slips (``kept_through_turns`` 1); the other (0) loses it at the turn. A gain
kept through presliding after a start depends on where exactly each fitted break-away
lies: on the project's own generator the gain after the median dwell came out 15-37 %
low on seeds 1-5 with the kept form, 2-16 % with the turn's. A table may hold either;
the diagnosis fits both and takes one worth an effect.

The width of each element's window grows with g, its height too; the design column is
the extra force at a gain ``reach`` (G) divided by G, so that its coefficient ``gamma``
is the gain when ``reach`` fits it, and with the shape (tau, reach) fixed the effect is
linear in ``gamma``. It needs the GMS it raises (``Context.gms``; per sample, ``stream``)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.config import in_range, positive
from gms_comp.gms import GmsParams
from gms_comp.runtime.effects.base import Effect
from gms_comp.runtime.effects.dwell_kernels import (
    N_TAIL,
    held_at_starts,
    levels_along,
    raised_run,
    raised_windows,
)
from gms_comp.runtime.effects.path import Context

# Time constants below this are held at it (a servo cycle: far below, the gain cannot be
# told from a constant one).
MIN_TAU_S = 1e-4
# Each element's raised limit is spread over break-aways within exp(+-SPREAD) of its own,
# on SPREAD_ELEMENTS sub-elements: the extra force of a raised element is a narrow window
# at its break-away, so a fitted break-away a little off puts its window off. With the
# baseline's elements on a grid (a factor 1.6 apart) a spread of +-0.25 was needed; with
# their break-aways fitted off the grid (baseline.refine_knots) +-0.1 correlates best
# with an independent truth's dwell force: 0.81-0.93 on nine of ten traces (+-0.25:
# 0.48-0.91, none: 0.62-0.95).
SPREAD = 0.1
SPREAD_ELEMENTS = 5
# Where a context keeps what its GMS's dwell columns share, for every shape: the held
# elements' forces at its starts, and the slip level at every sample.
HELD_KEY = "dwell_time.held_at_starts"
LEVELS_KEY = "dwell_time.levels"


def _sub_elements(w: FloatArray, breakaway_m: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The stiffnesses and limits of the sub-elements (``SPREAD_ELEMENTS`` each, in
    order) that spread elements of limits ``w`` over break-aways around theirs."""
    spread = np.exp(np.linspace(-SPREAD, SPREAD, SPREAD_ELEMENTS))
    sub_w = np.ascontiguousarray(np.repeat(w / SPREAD_ELEMENTS, SPREAD_ELEMENTS))
    return np.ascontiguousarray(sub_w / np.outer(breakaway_m, spread).ravel()), sub_w


class RaisedLimits:
    """``scale`` times the extra force of a GMS's limits raised (by ``reach``) after
    standstills, batch or per sample (one state carried from call to call); ``keep``:
    the gain kept through a turn until the element slips."""

    def __init__(
        self, gms: GmsParams, tau_s: float, reach: float, scale: float = 1.0, keep: float = 0.0
    ) -> None:
        active = gms.limit_N > 0.0
        w = gms.limit_N[active]
        self.k, self.w = _sub_elements(w, w / gms.stiffness_N_per_m[active])
        self.scalars = gms.scalars
        self.tau_s = max(tau_s, MIN_TAU_S)
        self.reach = reach
        self.scale = scale
        self.keep = float(keep)
        self.reset()

    def reset(self) -> None:
        """Virgin elements, no standstill seen."""
        self.state = np.zeros(6 * self.k.size + N_TAIL)
        # one sample's inputs (position, velocity, rest flag, dwell, direction) and output
        self._sample = np.zeros((5, 1))
        self._out = np.zeros(1)

    def run(self, ctx: Context) -> FloatArray:
        """The (scaled) extra force along ``ctx``, continuing from the current state."""
        out = np.empty(ctx.position_m.size)
        raised_run(self.k, self.w, self.scalars, self.reach, self.tau_s, self.keep,
                   *_path(ctx), self.state, out)  # fmt: skip
        return self.scale * out

    def levels(self, ctx: Context) -> FloatArray:
        """The slip level at every sample of ``ctx`` (:func:`levels_along`)."""
        return levels_along(_path(ctx)[1], self.scalars)

    def held_at_starts(self, ctx: Context, levels: FloatArray | None = None) -> FloatArray:
        """These elements' held forces at ``ctx``'s starts (:func:`held_at_starts`): the
        same for every ``tau_s`` and ``reach``; ``levels``: :meth:`levels`, if at hand."""
        x, _, resting, dwell, _ = _path(ctx)
        levels = self.levels(ctx) if levels is None else levels
        return held_at_starts(self.k, self.w, self.scalars, x, levels, resting, dwell)

    def from_rest(
        self, ctx: Context, held: FloatArray | None = None, levels: FloatArray | None = None
    ) -> FloatArray:
        """:meth:`run` from the virgin state (this object's state is neither read nor
        changed), the elements stepped only where the raised ones differ
        (:func:`raised_windows`); ``held`` (:meth:`held_at_starts`) and ``levels``
        (:meth:`levels`) on ``ctx``, if at hand."""
        levels = self.levels(ctx) if levels is None else levels
        held = self.held_at_starts(ctx, levels) if held is None else held
        x, _, resting, dwell, direction = _path(ctx)
        out = np.zeros(x.size)
        raised_windows(self.k, self.w, self.scalars, self.reach, self.tau_s, self.keep, x,
                       levels, resting, dwell, direction, held, out)  # fmt: skip
        return self.scale * out

    def step(
        self, position_m: float, velocity_m_s: float, resting: float, dwell_s: float,
        direction: float,
    ) -> float:  # fmt: skip
        """One sample of :meth:`run`, on preallocated buffers (a servo cycle's call); the
        path's rest flag, dwell and direction at that sample."""
        x, v, rest, dwell, turn = self._sample
        x[0], v[0], rest[0], dwell[0] = position_m, velocity_m_s, resting, dwell_s
        turn[0] = direction
        raised_run(self.k, self.w, self.scalars, self.reach, self.tau_s, self.keep,
                   x, v, rest, dwell, turn, self.state, self._out)  # fmt: skip
        return self.scale * float(self._out[0])


def _path(ctx: Context) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Position, velocity, rest flag, dwell and direction along ``ctx`` as the kernels
    take them."""
    x, v, resting, dwell, direction = (
        np.ascontiguousarray(a, dtype=np.float64)
        for a in (ctx.position_m, ctx.velocity_m_s, ctx.resting, ctx.dwell_s, ctx.direction)
    )
    return x, v, resting, dwell, direction


def _needs(gms: GmsParams | None, where: str) -> GmsParams:
    if gms is None:
        raise ValueError(f"dwell_time raises the GMS's own limits: the {where} needs its GMS")
    return gms


@dataclass(frozen=True)
class DwellTime(Effect):
    """Break-away limits raised by 1 + gamma ln(1 + t_d/tau) after a standstill, element
    by element (module docstring); ``reach`` is the gain the column's windows are
    computed at (the fit's shape parameter, gamma's own value when it fits);
    ``kept_through_turns`` 1: the spec's form, 0: the gain lost at a turn."""

    name: ClassVar[str] = "dwell_time"
    SHAPE: ClassVar[tuple[str, ...]] = ("tau_s", "reach", "kept_through_turns")
    gamma: float = field(metadata=in_range(0.0, 100.0))
    tau_s: float = field(metadata=positive(1e7))
    reach: float = field(metadata=positive(100.0))
    kept_through_turns: float = field(default=0.0, metadata=in_range(0.0, 1.0))

    def __post_init__(self) -> None:
        if self.kept_through_turns not in (0.0, 1.0):
            raise ValueError(f"kept_through_turns must be 0 or 1, got {self.kept_through_turns}")

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        """The raised GMS's extra force at the gain ``reach``, over ``reach``."""
        keep = shape.get("kept_through_turns", 0.0)
        raised = RaisedLimits(
            _needs(ctx.gms, "context"), shape["tau_s"], shape["reach"], 1 / shape["reach"], keep
        )
        # the elements are the context's own GMS's, so what it keeps is theirs
        if LEVELS_KEY not in ctx.derived:
            ctx.derived[LEVELS_KEY] = raised.levels(ctx)
        levels = ctx.derived[LEVELS_KEY]
        if HELD_KEY not in ctx.derived:
            ctx.derived[HELD_KEY] = raised.held_at_starts(ctx, levels)
        return raised.from_rest(ctx, ctx.derived[HELD_KEY], levels)[:, None]

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        """The effect with gain ``gamma = coefficients[0]``."""
        keep = shape.get("kept_through_turns", 0.0)
        return cls(float(coefficients[0]), shape["tau_s"], shape["reach"], keep)

    def coefficients(self) -> FloatArray:
        """``[gamma]``."""
        return np.array([self.gamma])

    def stream(self, gms: GmsParams | None) -> RaisedLimits:
        """The per-sample form: its elements' state is carried from sample to sample."""
        return RaisedLimits(_needs(gms, "stream"), self.tau_s, self.reach,
                            self.gamma / self.reach, self.kept_through_turns)  # fmt: skip
