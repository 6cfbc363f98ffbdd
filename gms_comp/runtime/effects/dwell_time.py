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
the diagnosis fits both (``FITTED_FORMS``) and takes one worth an effect.

The width of each element's window grows with g, its height too; the design column is
the extra force at a gain ``reach`` (G) divided by G, so that its coefficient ``gamma``
is the gain when ``reach`` fits it, and with the shape (tau, reach) fixed the effect is
linear in ``gamma``. It needs the GMS it raises (``Context.gms``; per sample, ``stream``)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

import numba
import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.gms import _PLAY, GmsParams, _level
from gms_comp.runtime.effects.base import Effect, Shape, duration
from gms_comp.runtime.effects.leftover import Leftover
from gms_comp.runtime.effects.path import REST_HOLD_S, Context

# The time constants the diagnosis considers (s): far below a servo cycle or above a
# trace's length a dwell gain cannot be told from a constant one.
TAU_RANGE_S = (1e-4, 1e2)
# The forms at a turn the diagnosis fits, each from its own starts, a form worth an
# effect taken before a better held-out one (selection._forms; the better held out alone
# lost dwell_time-146, -157, -182 of the independent generator to `none`).
FITTED_FORMS = (0.0, 1.0)
# The gains at which the column's windows are computed (G: 0.5 % to 1.5 x the limits).
REACH_RANGE = (5e-3, 1.5)
# Each element's raised limit is spread over break-aways within exp(+-SPREAD) of its own,
# on SPREAD_ELEMENTS sub-elements: the extra force of a raised element is a narrow window
# at its break-away, so a fitted break-away a little off puts its window off. With the
# baseline's elements on a grid (a factor 1.6 apart) a spread of +-0.25 was needed; with
# their break-aways fitted off the grid (baseline.refine_knots) +-0.1 correlates best
# with an independent truth's dwell force: 0.81-0.93 on nine of ten traces (+-0.25:
# 0.48-0.91, none: 0.62-0.95).
SPREAD = 0.1
SPREAD_ELEMENTS = 5
# Where a context keeps its GMS's held elements' forces at its starts (they depend on the
# GMS and the path only, not on the shape).
HELD_KEY = "dwell_time.held_at_starts"
# Layout of the state after the 6 element vectors: last position, last rest flag, first,
# the direction of the move since the last start (:func:`_turned`) and where it began.
_PREV_X, _PREV_REST, _FIRST, _MOVE, _START_X, _N_TAIL = range(6)
# The move since a start: its direction not yet known, and turned back (the gain lost).
_UNKNOWN, _TURNED = 0.0, 2.0


@numba.njit(cache=True, inline="always")
def _turned(move: float, start_x: float, x: float, direction: float) -> tuple[float, bool]:
    """The move since a start, and whether it turns back at this sample. Its direction
    is the path's (reversal deadband included) once the position has gone that way from
    the start (a start against the last move flips the causal path's direction only
    after the deadband; one dated in hindsight, where the rest ends); the first flip
    after that is the turn."""
    if move == _UNKNOWN and direction * (x - start_x) > 0.0:
        return direction, False
    if (move == 1.0 or move == -1.0) and direction == -move:
        return _TURNED, True
    return move, False


@numba.njit(cache=True, inline="always")
def _rule(
    fi: float, di: float, gi: float, ki: float, wi: float, dx: float, level: float,
    play: float,
) -> tuple[float, float, float]:  # fmt: skip
    """One element's force, slip direction and hold after a move ``dx``: a Maxwell-slip
    element (the GMS kernel's rule, rate-independent; ``play``: its limit follows the
    level) that, while held since a start (hold g >= 1), slips only beyond g times its
    limit at the current speed, and is the kernel's element again (g = 0) once it has.
    Branch-free, so that a loop of it vectorises."""
    sliding = di != 0.0 and di * dx >= 0.0 and play == 0.0
    stretch = (fi if di == 0.0 or play != 0.0 else di * wi) + ki * dx
    threshold = wi * level * gi if gi >= 1.0 else (wi * level if play != 0.0 else wi)
    up = stretch > threshold
    down = stretch < -threshold
    f = di * level * wi if sliding else (level * wi if up else (-level * wi if down else stretch))
    d = di if sliding else (1.0 if up else (-1.0 if down else 0.0))
    return f, d, (gi if sliding else (0.0 if up or down else gi))


@numba.njit(cache=True)
def _raised_run(
    k: FloatArray, w: FloatArray, scalars: FloatArray, reach: float, tau: float,
    keep: float, x: FloatArray, v: FloatArray, resting: FloatArray, dwell: FloatArray,
    direction: FloatArray, state: FloatArray, out: FloatArray,
) -> None:  # fmt: skip
    """The raised elements' force less that of the same elements held to their plain
    limits, per sample: at a start both stick where they rested and slip at their limit
    at the current speed, times the gain or times 1, so the difference is the gain's
    alone (the climb from the stick to the sliding level belongs to the baseline). Where
    the move turns back before an element has slipped (:func:`_turned`), its gain is
    lost (unless ``keep``): the raised elements become the held ones.
    ``state`` (6 n + ``_N_TAIL``: the held elements' forces, slip directions and holds,
    the raised ones' alike, then the scalars) is advanced in place, so a
    stream of one-sample calls equals one batch.

    Each element follows :func:`_rule`. The held and the raised elements are one vector
    of 2 n, updated without branches (so that the compiler vectorises it), then summed
    in order."""
    n = k.size
    play = scalars[_PLAY]
    tail = 6 * n
    # fresh local copies, the held elements then the raised ones: they alias nothing
    kk = np.concatenate((k, k))
    ww = np.concatenate((w, w))
    f = np.concatenate((state[0:n], state[3 * n : 4 * n]))
    d = np.concatenate((state[n : 2 * n], state[4 * n : 5 * n]))
    g = np.concatenate((state[2 * n : 3 * n], state[5 * n : 6 * n]))
    for j in range(x.size):
        if state[tail + _FIRST] == 0.0:
            state[tail + _PREV_X] = x[j]
            state[tail + _FIRST] = 1.0
        dx = x[j] - state[tail + _PREV_X]
        state[tail + _PREV_X] = x[j]
        level = _level(abs(v[j]), scalars)
        if resting[j] == 0.0 and state[tail + _PREV_REST] == 1.0 and dwell[j] >= REST_HOLD_S:
            # the motion resumes: every element sticks where it rested, held
            gain = 1.0 + reach * math.log1p(dwell[j] / tau)
            for i in range(n):
                d[i], g[i] = 0.0, 1.0
                d[n + i], g[n + i] = 0.0, gain
            state[tail + _MOVE], state[tail + _START_X] = _UNKNOWN, x[j]
        state[tail + _PREV_REST] = resting[j]
        state[tail + _MOVE], lost = _turned(
            state[tail + _MOVE], state[tail + _START_X], x[j], direction[j]
        )
        if lost and keep == 0.0:
            for i in range(n):
                f[n + i], d[n + i], g[n + i] = f[i], d[i], g[i]
        for i in range(2 * n):
            f[i], d[i], g[i] = _rule(f[i], d[i], g[i], kk[i], ww[i], dx, level, play)
        extra = 0.0
        for i in range(n):
            extra += f[n + i] - f[i]
        out[j] = extra
    state[0:n], state[n : 2 * n], state[2 * n : 3 * n] = f[:n], d[:n], g[:n]
    state[3 * n : 4 * n], state[4 * n : 5 * n], state[5 * n : 6 * n] = f[n:], d[n:], g[n:]


@numba.njit(cache=True)
def _held_at_starts(
    k: FloatArray, w: FloatArray, scalars: FloatArray, x: FloatArray, v: FloatArray,
    resting: FloatArray, dwell: FloatArray,
) -> FloatArray:  # fmt: skip
    """The held elements' forces at every start (a row each), from the virgin state:
    :func:`_raised_run`'s first n elements, which no shape changes."""
    n = k.size
    play = scalars[_PLAY]
    starts = 0
    for j in range(1, x.size):
        if resting[j] == 0.0 and resting[j - 1] == 1.0 and dwell[j] >= REST_HOLD_S:
            starts += 1
    out = np.zeros((starts, n))
    f, d, g = np.zeros(n), np.zeros(n), np.zeros(n)
    row = 0
    for j in range(x.size):
        if j > 0 and resting[j] == 0.0 and resting[j - 1] == 1.0 and dwell[j] >= REST_HOLD_S:
            d[:] = 0.0
            g[:] = 1.0
            out[row] = f
            row += 1
        dx = x[j] - x[j - 1] if j > 0 else 0.0
        level = _level(abs(v[j]), scalars)
        for i in range(n):
            f[i], d[i], g[i] = _rule(f[i], d[i], g[i], k[i], w[i], dx, level, play)
    return out


@numba.njit(cache=True)
def _raised_windows(
    k: FloatArray, w: FloatArray, scalars: FloatArray, reach: float, tau: float,
    keep: float, x: FloatArray, v: FloatArray, resting: FloatArray, dwell: FloatArray,
    direction: FloatArray, held: FloatArray, out: FloatArray,
) -> None:  # fmt: skip
    """:func:`_raised_run` from the virgin state, bit for bit, element by element only
    while it differs: once an element's raised copy has slipped to the same force,
    direction and hold as its held one (or has become it where the move turned back),
    the two stay equal (and add exactly 0) until the
    next start, where both take the held force kept at that start (``held``:
    :func:`_held_at_starts`). On independent traces 2-4 % of the element steps are left,
    and a column costs 2-5 ms instead of 17-19 ms (with the turn's form; the gain kept
    through turns keeps elements live through presliding runs)."""
    n = k.size
    play = scalars[_PLAY]
    fh, dh, gh = np.zeros(n), np.zeros(n), np.zeros(n)
    fr, dr, gr = np.zeros(n), np.zeros(n), np.zeros(n)
    live = np.zeros(n, dtype=np.int64)  # the elements that differ, in order
    is_live = np.zeros(n, dtype=np.bool_)
    m = 0
    row = 0
    move, start_x = _TURNED, 0.0
    for j in range(x.size):
        if j > 0 and resting[j] == 0.0 and resting[j - 1] == 1.0 and dwell[j] >= REST_HOLD_S:
            gain = 1.0 + reach * math.log1p(dwell[j] / tau)
            for i in range(n):
                if not is_live[i]:
                    fh[i] = fr[i] = held[row, i]
                dh[i], gh[i], dr[i], gr[i] = 0.0, 1.0, 0.0, gain
                live[i], is_live[i] = i, True
            m = n
            row += 1
            move, start_x = _UNKNOWN, x[j]
        if m == 0:
            out[j] = 0.0
            continue
        move, lost = _turned(move, start_x, x[j], direction[j])
        if lost and keep == 0.0:
            for q in range(m):
                i = live[q]
                fr[i], dr[i], gr[i] = fh[i], dh[i], gh[i]
                is_live[i] = False
            m = 0
            out[j] = 0.0
            continue
        dx = x[j] - x[j - 1] if j > 0 else 0.0
        level = _level(abs(v[j]), scalars)
        kept = 0
        extra = 0.0
        for q in range(m):
            i = live[q]
            fh[i], dh[i], gh[i] = _rule(fh[i], dh[i], gh[i], k[i], w[i], dx, level, play)
            fr[i], dr[i], gr[i] = _rule(fr[i], dr[i], gr[i], k[i], w[i], dx, level, play)
            extra += fr[i] - fh[i]
            if fr[i] == fh[i] and dr[i] == dh[i] and gr[i] == gh[i]:
                is_live[i] = False
            else:
                live[kept] = i
                kept += 1
        out[j] = extra
        m = kept


class RaisedLimits:
    """``scale`` times the extra force of a GMS's limits raised (by ``reach``) after
    standstills, batch or per sample (one state carried from call to call); ``keep``:
    the gain kept through a turn until the element slips."""

    def __init__(
        self, gms: GmsParams, tau_s: float, reach: float, scale: float = 1.0, keep: float = 0.0
    ) -> None:
        active = gms.limit_N > 0.0
        w = gms.limit_N[active]
        spread = np.exp(np.linspace(-SPREAD, SPREAD, SPREAD_ELEMENTS))
        breakaway = np.outer(w / gms.stiffness_N_per_m[active], spread).ravel()
        self.w = np.ascontiguousarray(np.repeat(w / SPREAD_ELEMENTS, SPREAD_ELEMENTS))
        self.k = np.ascontiguousarray(self.w / breakaway)
        self.scalars = gms.scalars
        self.tau_s = max(tau_s, TAU_RANGE_S[0])
        self.reach = reach
        self.scale = scale
        self.keep = float(keep)
        self.reset()

    def reset(self) -> None:
        """Virgin elements, no standstill seen."""
        self.state = np.zeros(6 * self.k.size + _N_TAIL)
        # one sample's inputs (position, velocity, rest flag, dwell, direction) and output
        self._sample = np.zeros((5, 1))
        self._out = np.zeros(1)

    def run(self, ctx: Context) -> FloatArray:
        """The (scaled) extra force along ``ctx``, continuing from the current state."""
        out = np.empty(ctx.position_m.size)
        _raised_run(self.k, self.w, self.scalars, self.reach, self.tau_s, self.keep,
                    *_path(ctx), self.state, out)  # fmt: skip
        return self.scale * out

    def held_at_starts(self, ctx: Context) -> FloatArray:
        """These elements' held forces at ``ctx``'s starts (:func:`_held_at_starts`): the
        same for every ``tau_s`` and ``reach``."""
        x, v, resting, dwell, _ = _path(ctx)
        return _held_at_starts(self.k, self.w, self.scalars, x, v, resting, dwell)

    def from_rest(self, ctx: Context, held: FloatArray | None = None) -> FloatArray:
        """:meth:`run` from the virgin state (this object's state is neither read nor
        changed), the elements stepped only where the raised ones differ
        (:func:`_raised_windows`); ``held``: :meth:`held_at_starts` on ``ctx``, if at
        hand."""
        held = self.held_at_starts(ctx) if held is None else held
        out = np.empty(ctx.position_m.size)
        _raised_windows(self.k, self.w, self.scalars, self.reach, self.tau_s, self.keep,
                        *_path(ctx), held, out)  # fmt: skip
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
        _raised_run(self.k, self.w, self.scalars, self.reach, self.tau_s, self.keep,
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
    SET_BY_SIZE: ClassVar[tuple[str, ...]] = ("reach",)
    COEFFICIENT_LOWER: ClassVar[float] = 0.0
    gamma: float
    tau_s: float
    reach: float
    kept_through_turns: float = 0.0

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
        held = ctx.derived.get(HELD_KEY)
        if held is None:
            held = ctx.derived[HELD_KEY] = raised.held_at_starts(ctx)
        return raised.from_rest(ctx, held)[:, None]

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        """The effect with gain ``gamma = coefficients[0]``."""
        keep = shape.get("kept_through_turns", 0.0)
        return cls(float(coefficients[0]), shape["tau_s"], shape["reach"], keep)

    def coefficients(self) -> FloatArray:
        """``[gamma]``."""
        return np.array([self.gamma])

    @classmethod
    def consistent_shape(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Shape:
        """The windows computed at the fitted gain (``reach = gamma``, within its range):
        a column computed at one gain and scaled to another is a different force (on an
        effect-free trace a gain of 264 on windows computed at 0.014 fitted spikes at
        the starts)."""
        return {**shape, "reach": float(np.clip(coefficients[0], *REACH_RANGE))}

    def in_context(self, ctx: Context) -> dict[str, float]:
        """The median standstill before the starts along ``ctx`` and the break-away gain
        after it, gamma ln(1 + t/tau): what a trace's starts determine. Over dwells of
        0.05-3 s, (gamma, tau) pairs with the same gains at those dwells fit alike (on an
        independent trace the whole-trace RMS differed by 3e-5 relative between tau 0.15
        and 0.42 s), so gamma alone follows the tau chosen."""
        dwells = ctx.dwell_s[ctx.starts()]
        dwells = dwells[dwells > 0.0]
        if dwells.size == 0:
            return {}
        median = float(np.median(dwells))
        return {
            "median_dwell_s": median,
            "gain_after_median_dwell": self.gamma * math.log1p(median / self.tau_s),
        }

    def relative_size(self, ctx: Context) -> float | None:
        """The break-away gain after the median standstill (:meth:`in_context`): with
        the windows fitted to the starts' residual, a gain of 0.3 % (on an independent
        effect-free trace, a bump of one start the baseline missed) can change the model
        force by more than its 2 %."""
        return self.in_context(ctx).get("gain_after_median_dwell", 0.0)

    def stream(self, gms: GmsParams | None) -> RaisedLimits:
        """The per-sample form: its elements' state is carried from sample to sample."""
        return RaisedLimits(_needs(gms, "stream"), self.tau_s, self.reach,
                            self.gamma / self.reach, self.kept_through_turns)  # fmt: skip

    @classmethod
    def shape_grid(cls, ctx: Context, left: Leftover, presliding_m: float) -> list[Shape]:
        """tau over the decades from :func:`shortest_tau` to the trace's length; gains
        3-30 %; the forms at a turn in ``FITTED_FORMS``."""
        lo, hi = cls.shape_bounds(ctx, presliding_m)["tau_s"]
        return [
            {"tau_s": float(tau), "reach": reach, "kept_through_turns": keep}
            for tau in np.geomspace(lo, max(min(hi, duration(ctx)), 2 * lo), 9)
            for reach in (0.03, 0.1, 0.3)
            for keep in FITTED_FORMS
        ]

    @classmethod
    def shape_bounds(cls, ctx: Context, presliding_m: float) -> dict[str, tuple[float, float]]:
        """tau from :func:`shortest_tau` to ``TAU_RANGE_S``'s top, the gain in
        ``REACH_RANGE`` (the form at a turn is not searched: a discrete key)."""
        return {"tau_s": (shortest_tau(ctx), TAU_RANGE_S[1]), "reach": REACH_RANGE}


def shortest_tau(ctx: Context) -> float:
    """The shortest time constant a dwell gain is fitted with: a tenth of the median
    standstill before the starts (rests of at least the path's ``REST_HOLD_S``; shorter
    ones raise no limits). Far below every dwell, ln(1 + t_d / tau) hardly changes with
    the dwell (from 0.05 to 3 s at tau = 1 ms: 3.9 to 8.0), so the gain is the same at
    every start, and on an effect-free trace such a column took up the baseline's
    mismatch at starts (held-out gain 4 %); at a tenth of the median it still grows 2.2 x
    from a fifth of the median dwell to the median."""
    dwells = ctx.dwell_s[ctx.starts()]
    dwells = dwells[dwells > 0.0]
    if dwells.size == 0:
        return TAU_RANGE_S[0]
    return float(np.clip(0.1 * np.median(dwells), *TAU_RANGE_S))
