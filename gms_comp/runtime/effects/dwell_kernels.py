"""The dwell-time effect's per-element kernels (:mod:`~gms_comp.runtime.effects.dwell_time`):
a GMS's elements held since a start, and the same elements with their limits raised, per
sample (:func:`raised_run`, streaming) or from rest, element by element only while they
differ (:func:`raised_windows`, a diagnosis column). The slip level at every sample is
an input of the batch kernels (:func:`levels_along`), computed once per GMS."""

from __future__ import annotations

import math

import numba
import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.gms import _PLAY, _level
from gms_comp.runtime.effects.path import REST_HOLD_S

# Layout of the state after the 6 element vectors: last position, last rest flag, first,
# the direction of the move since the last start (:func:`_turned`) and where it began.
_PREV_X, _PREV_REST, _FIRST, _MOVE, _START_X, N_TAIL = range(6)
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
def raised_run(
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
    ``state`` (6 n + ``N_TAIL``: the held elements' forces, slip directions and holds,
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
def held_at_starts(
    k: FloatArray, w: FloatArray, scalars: FloatArray, x: FloatArray, levels: FloatArray,
    resting: FloatArray, dwell: FloatArray,
) -> FloatArray:  # fmt: skip
    """The held elements' forces at every start (a row each), from the virgin state:
    :func:`raised_run`'s first n elements, which no shape changes (``levels``: the slip
    level at every sample, :func:`levels_along`)."""
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
        for i in range(n):
            f[i], d[i], g[i] = _rule(f[i], d[i], g[i], k[i], w[i], dx, levels[j], play)
    return out


@numba.njit(cache=True)
def raised_windows(
    k: FloatArray, w: FloatArray, scalars: FloatArray, reach: float, tau: float,
    keep: float, x: FloatArray, levels: FloatArray, resting: FloatArray, dwell: FloatArray,
    direction: FloatArray, held: FloatArray, out: FloatArray,
) -> None:  # fmt: skip
    """:func:`raised_run` from the virgin state, element by element only while it
    differs: once an element's raised copy has slipped to the same force, direction and
    hold as its held one (or has become it where the move turned back), the two stay
    equal (and add exactly 0) until the next start, where both take the held force kept
    at that start (``held``: :func:`held_at_starts`). On independent traces 2-4 % of the
    element steps are left, and a column costs 2-5 ms instead of 17-19 ms (with the
    turn's form; the gain kept through turns keeps elements live through presliding
    runs). While both copies stick at one force, only the held one is stepped: most of
    what is left on a step-and-stop trace's rests, where the widest elements never slip
    (27 -> 20 ms on dwell_time-235 of the independent generator, 50 elements). The
    elements' differences are added to ``out`` (zeros on entry): bit for bit
    :func:`raised_run`'s. ``levels``: :func:`levels_along`."""
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
            continue
        move, lost = _turned(move, start_x, x[j], direction[j])
        if lost and keep == 0.0:
            for q in range(m):
                i = live[q]
                fr[i], dr[i], gr[i] = fh[i], dh[i], gh[i]
                is_live[i] = False
            m = 0
            continue
        dx = x[j] - x[j - 1] if j > 0 else 0.0
        level = levels[j]
        kept = 0
        for q in range(m):
            i = live[q]
            # both copies stuck at one force since the start: while the held one sticks,
            # so does the raised one (its limit is higher), at the same force
            twin = dh[i] == 0.0 and dr[i] == 0.0 and fr[i] == fh[i] and gr[i] >= gh[i] >= 1.0
            fh[i], dh[i], gh[i] = _rule(fh[i], dh[i], gh[i], k[i], w[i], dx, level, play)
            if twin and dh[i] == 0.0:
                fr[i] = fh[i]
            else:
                fr[i], dr[i], gr[i] = _rule(fr[i], dr[i], gr[i], k[i], w[i], dx, level, play)
                out[j] += fr[i] - fh[i]
            if fr[i] == fh[i] and dr[i] == dh[i] and gr[i] == gh[i]:
                is_live[i] = False
            else:
                live[kept] = i
                kept += 1
        m = kept


@numba.njit(cache=True)
def levels_along(v: FloatArray, scalars: FloatArray) -> FloatArray:
    """The slip level s(|v|) at every sample (the GMS kernel's)."""
    out = np.empty(v.size)
    for j in range(v.size):
        out[j] = _level(abs(v[j]), scalars)
    return out
