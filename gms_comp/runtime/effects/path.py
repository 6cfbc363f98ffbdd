"""Path quantities along a trajectory: what a catalogue effect sees (:class:`Context`).

Direction of motion, distance since the last reversal, length of the last standstill,
distance since the motion resumed and time elapsed come from one numba per-sample routine
that serves both the batch :meth:`Context.along` and the streaming
:class:`~gms_comp.runtime.effects.stream.ExtensionStream`. A batch context may date its
reversals in hindsight (``hindsight=True``, as the diagnosis does): from the turning
point, which a streaming compensator learns of only once the retreat exceeds the
deadband; otherwise the two are equal sample for sample.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike

from gms_comp.arrays import BoolArray, FloatArray, IntArray
from gms_comp.gms import GmsParams
from gms_comp.kinematics import Kinematics

# Below this speed an axis counts as standing still unless a caller says otherwise.
DEFAULT_STANDSTILL_SPEED_M_S = 1e-4

# A standstill ends once the speed exceeds this multiple of the standstill speed.
RESUME_FACTOR = 2.0

# With a rest band, a position held within it this long is a rest, and a rest this long
# ends when the position leaves the band (before that, leaving it is the stop settling).
REST_HOLD_S = 0.02
# ... and held at least this many times as long as the position took to cross the band
# before it. At a slow turnaround the position stays within the band too (a parabola's
# vertex: 20-60 ms on an independent generator's micrometre reversals, where the old rule
# dated 2-20 rests per trace that the truth does not have), but for only about 5 times
# its last crossing; at a stop for far longer. On that generator's ten dwell traces 5 left
# one false rest, 7 none, and every one of its 202 real rests kept its date and length.
TURN_FACTOR = 7.0
# While resting, a move of this share of the band is an encoder step (half a step at the
# diagnosis's default band of 1.5 steps): a slow start is dated from its first one.
STEP_SHARE = 1.0 / 3.0

# Layout of the path-state vector.
(_FIRST, _PREV_X, _CUM, _DIR, _CUM_AT_REVERSAL, _STILL, _STILL_SINCE, _DWELL, _CUM_AT_RESUME,
 _T0, _EXTREME, _CUM_AT_EXTREME, _REST, _ANCHOR, _CAND_X, _CAND_T, _CROSS, _STEP_X, _STEP_T,
 _STEP_DIR, _N_STATE) = range(21)  # fmt: skip
# Layout of one output row.
(_OUT_DIR, _OUT_S_REV, _OUT_DWELL, _OUT_S_START, _OUT_MOVING, _OUT_RESTING, _OUT_ELAPSED,
 N_OUT) = range(8)  # fmt: skip


@numba.njit(cache=True)
def _direction_step(state: FloatArray, x: float, deadband: float) -> None:
    """Direction of motion from the position: a reversal is a retreat of more than
    ``deadband`` from the furthest point reached, and counts from that turning point
    (so encoder steps and filter ringing at a standstill make no reversals). The first
    move of more than ``deadband`` from the first sample sets the direction; it is not a
    reversal. (Set by the first nonzero speed, the direction came from a smoothed speed's
    rounding residue at the first sample, about 1e-71 m/s, of either sign: on 13 of 30
    seeds of an independent generator the first stroke then counted as a reversal and
    carried a full reversal transient, and reversal_transient-124's amplitude came out
    0.79 N for 3.87 N.)"""
    d = state[_DIR]
    if d == 0.0:
        if abs(x - state[_EXTREME]) > deadband:
            state[_DIR] = 1.0 if x > state[_EXTREME] else -1.0
            state[_EXTREME] = x
            state[_CUM_AT_EXTREME] = state[_CUM]
    elif (x - state[_EXTREME]) * d >= 0.0:
        state[_EXTREME] = x
        state[_CUM_AT_EXTREME] = state[_CUM]
    elif (state[_EXTREME] - x) * d > deadband:
        state[_DIR] = -d
        state[_CUM_AT_REVERSAL] = state[_CUM_AT_EXTREME]
        state[_EXTREME] = x
        state[_CUM_AT_EXTREME] = state[_CUM]


@numba.njit(cache=True)
def _start(state: FloatArray, x: float, began: float) -> None:
    """The motion resumes (it began at ``began``): the dwell ends and the distance counts
    from the rest position. A rest from the first sample began before the path did: its
    length is unknown, and its dwell is 0 (no standstill seen)."""
    known = state[_STILL_SINCE] > state[_T0]
    state[_DWELL] = began - state[_STILL_SINCE] if known else 0.0
    state[_CUM_AT_RESUME] = state[_CUM] - abs(x - state[_ANCHOR])
    state[_REST] = 0.0


@numba.njit(cache=True)
def _rested(state: FloatArray, t: float, anchor: float, x: float) -> None:
    """A rest from ``t`` around ``anchor``, the position now ``x`` (no step off it yet)."""
    state[_REST] = 1.0
    state[_ANCHOR] = anchor
    state[_STILL_SINCE] = t
    state[_STEP_X] = x
    state[_STEP_T] = t
    state[_STEP_DIR] = 0.0


@numba.njit(cache=True)
def _rest_step(state: FloatArray, t: float, x: float, still: bool, band: float) -> None:
    """The rest (standstill) state: entered when the speed falls below the standstill speed
    or, with a ``band``, when the position has stayed within it for ``REST_HOLD_S`` and
    ``TURN_FACTOR`` times its last crossing of the band (not a slow turnaround); left
    when the speed rises again or, after a rest of ``REST_HOLD_S``, when the position
    leaves the band around where it came to rest (so a slow break-away is dated and
    measured from its first steps, not from when it reaches the standstill speed)."""
    was_still = state[_STILL] == 1.0
    if abs(x - state[_CAND_X]) > band:
        # how long the position took to cross the band (unknown as it leaves a rest)
        state[_CROSS] = 0.0 if state[_REST] == 1.0 else t - state[_CAND_T]
        state[_CAND_X] = x
        state[_CAND_T] = t
    if state[_REST] == 1.0:
        if not still:
            _start(state, x, t)
        elif band > 0.0 and abs(x - state[_ANCHOR]) > band:
            if t - state[_STILL_SINCE] < REST_HOLD_S:  # still settling: rest from here
                _rested(state, t, x, x)
            else:
                # a slow start leaves the band a step after it began: dated from that
                # step if it went the same way shortly before (not the stop's settling)
                first = state[_STEP_DIR] * (x - state[_ANCHOR]) > 0.0
                first = first and t - state[_STEP_T] < REST_HOLD_S
                _start(state, x, state[_STEP_T] if first else t)
        elif band > 0.0 and abs(x - state[_STEP_X]) > STEP_SHARE * band:  # an encoder step
            state[_STEP_DIR] = 1.0 if x > state[_STEP_X] else -1.0
            state[_STEP_X] = x
            state[_STEP_T] = t
    elif still and not was_still:
        _rested(state, t, x, x)
    elif band > 0.0 and t - state[_CAND_T] >= max(REST_HOLD_S, TURN_FACTOR * state[_CROSS]):
        _rested(state, state[_CAND_T], state[_CAND_X], x)


@numba.njit(cache=True)
def path_step(
    state: FloatArray, t: float, x: float, v: float, still_speed: float, deadband: float,
    rest_band: float, out: FloatArray,
) -> None:  # fmt: skip
    """Advance the path ``state`` by one sample and write its quantities to ``out``."""
    first = state[_FIRST] == 1.0
    dx = 0.0 if first else x - state[_PREV_X]
    state[_CUM] += abs(dx)
    if first:
        state[_T0] = t
        state[_CAND_X] = x
        state[_CAND_T] = t
        state[_EXTREME] = x  # where the first move is measured from
    _direction_step(state, x, deadband)
    # hysteresis: a noisy speed near the threshold must not make many short standstills
    still = abs(v) < (RESUME_FACTOR * still_speed if state[_STILL] == 1.0 else still_speed)
    _rest_step(state, t, x, still, rest_band)
    state[_STILL] = 1.0 if still else 0.0
    state[_PREV_X] = x
    state[_FIRST] = 0.0
    out[_OUT_DIR] = state[_DIR]
    out[_OUT_S_REV] = state[_CUM] - state[_CUM_AT_REVERSAL]
    out[_OUT_DWELL] = state[_DWELL]
    out[_OUT_S_START] = state[_CUM] - state[_CUM_AT_RESUME]
    out[_OUT_MOVING] = 0.0 if still else 1.0
    out[_OUT_RESTING] = state[_REST]
    out[_OUT_ELAPSED] = t - state[_T0]


@numba.njit(cache=True)
def _path_run(
    state: FloatArray, t: FloatArray, x: FloatArray, v: FloatArray, still_speed: float,
    deadband: float, rest_band: float,
) -> FloatArray:  # fmt: skip
    out = np.empty((t.size, N_OUT))
    for i in range(t.size):
        path_step(state, t[i], x[i], v[i], still_speed, deadband, rest_band, out[i])
    return out


@numba.njit(cache=True)
def _turned_at_extreme(
    x: FloatArray, resting: FloatArray, direction: FloatArray, s_rev: FloatArray
) -> None:
    """Date each reversal in hindsight, in place: from the turning point (the last sample
    at the old direction's extreme, as the causal routine keeps it), or from the end of a
    rest after it, not from where the retreat exceeded the deadband. The distance since
    it counts from there already; the samples in between get the new direction and their
    distance from the turning point. (A rest whose position dithers by a count leaves its
    last sample at the extreme anywhere in it: the motion turns where the rest ends.)"""
    turn = 0  # the last sample at the current direction's extreme, or resting after it
    for i in range(1, x.size):
        d = direction[i - 1]
        if d == 0.0:
            turn = i
            continue
        if direction[i] == -d:
            cum = 0.0
            for k in range(turn + 1, i):
                cum += abs(x[k] - x[k - 1])
                direction[k] = -d
                s_rev[k] = cum
            turn = i
        elif (x[i] - x[turn]) * d >= 0.0 or resting[i] > 0.0:
            turn = i


def fresh_path_state() -> FloatArray:
    """The path state before the first sample."""
    state = np.zeros(_N_STATE)
    state[_FIRST] = 1.0
    # the last reversal before the trajectory is unknown: until the first one, the
    # distance since a reversal is infinite (a transient of it has decayed; counting it
    # from the first motion put a full reversal transient on every trace's first stroke:
    # on an independent trace, A came out 0.26 for 1.0)
    state[_CUM_AT_REVERSAL] = -np.inf
    return state


@dataclass(frozen=True)
class Context:
    """What an effect sees along a trajectory (arrays of one length, or 1-element arrays
    for one streaming sample)."""

    time_s: FloatArray
    position_m: FloatArray
    velocity_m_s: FloatArray
    acceleration_m_s2: FloatArray
    gms_force_N: FloatArray
    direction: FloatArray
    distance_since_reversal_m: FloatArray
    dwell_s: FloatArray
    distance_since_start_m: FloatArray
    moving: FloatArray
    resting: FloatArray
    elapsed_s: FloatArray
    sample_time_s: float
    # the GMS whose force ``gms_force_N`` is (an effect that raises its elements' limits
    # needs them; None where only the force is known: ``dataclasses.replace`` sets it)
    gms: GmsParams | None = None

    @classmethod
    def along(
        cls,
        time_s: ArrayLike,
        position_m: ArrayLike,
        velocity_m_s: ArrayLike,
        acceleration_m_s2: ArrayLike,
        gms_force_N: ArrayLike,
        standstill_speed_m_s: float = DEFAULT_STANDSTILL_SPEED_M_S,
        reversal_deadband_m: float = 0.0,
        rest_band_m: float = 0.0,
        path_position_m: ArrayLike | None = None,
        *,
        hindsight: bool = False,
    ) -> Context:
        """The context of a whole trajectory (a reversal needs a retreat of more than
        ``reversal_deadband_m``: set it above the position noise; a rest ends when the
        position leaves ``rest_band_m`` around where it stopped, or with 0 when the speed
        exceeds the standstill speed). ``path_position_m``: the position the path (its
        reversals, rests and distances) is traced on, if not ``position_m``. With
        ``hindsight``, a reversal is dated from its turning point, which a recorded trace
        knows but a streaming compensator learns only once the retreat exceeds the
        deadband."""
        t = np.ascontiguousarray(time_s, dtype=np.float64)
        x = np.ascontiguousarray(position_m, dtype=np.float64)
        v = np.ascontiguousarray(velocity_m_s, dtype=np.float64)
        traced = x if path_position_m is None else np.ascontiguousarray(path_position_m, float)
        path = _path_run(
            fresh_path_state(), t, traced, v, standstill_speed_m_s, reversal_deadband_m,
            rest_band_m,
        )  # fmt: skip
        if hindsight:
            _turned_at_extreme(
                traced, path[:, _OUT_RESTING], path[:, _OUT_DIR], path[:, _OUT_S_REV]
            )
        dt = float((t[-1] - t[0]) / (t.size - 1)) if t.size > 1 else 0.0
        # column-major, so that each path quantity is contiguous: the kernels take
        # contiguous arrays, and strided columns were copied again on every call (3.7 of
        # 47 s of a trace); a streaming step's one row needs no copy
        return cls.with_path(
            t, x, v, np.asarray(acceleration_m_s2, float), np.asarray(gms_force_N, float),
            np.asfortranarray(path), dt,
        )  # fmt: skip

    @functools.cached_property
    def derived(self) -> dict[str, FloatArray]:
        """Arrays an effect derives from this context alone, kept for its next call (a
        dwell column's held elements at the starts: the same for every shape, 10 ms)."""
        return {}

    def after_rest(self) -> BoolArray:
        """The samples after the first rest: every motion there resumed from one (a rest
        from the record's first sample counts, though its dwell, unknown, is 0)."""
        return np.maximum.accumulate(self.resting > 0.0)

    def starts(self, hold_s: float = REST_HOLD_S) -> IntArray:
        """The samples where the motion resumes after a rest of at least ``hold_s`` (a rest
        from the record's first sample by the length seen)."""
        ends = np.flatnonzero((self.resting[:-1] > 0.0) & (self.resting[1:] == 0.0)) + 1
        held = self.dwell_s[ends] >= hold_s
        if ends.size and self.resting[0] > 0.0:
            held[0] = self.time_s[ends[0]] - self.time_s[0] >= hold_s
        return ends[held]

    @classmethod
    def of(
        cls,
        motion: Kinematics,
        gms_force_N: ArrayLike,
        standstill_speed_m_s: float = DEFAULT_STANDSTILL_SPEED_M_S,
        reversal_deadband_m: float = 0.0,
        rest_band_m: float = 0.0,
        path_position_m: ArrayLike | None = None,
        *,
        hindsight: bool = False,
    ) -> Context:
        """The context along ``motion`` (see :meth:`along`)."""
        return cls.along(
            motion.time_s,
            motion.position_m,
            motion.velocity_m_s,
            motion.acceleration_m_s2,
            gms_force_N,
            standstill_speed_m_s,
            reversal_deadband_m,
            rest_band_m,
            path_position_m,
            hindsight=hindsight,
        )

    @classmethod
    def with_path(
        cls, t: FloatArray, x: FloatArray, v: FloatArray, a: FloatArray, f: FloatArray,
        path: FloatArray, sample_time_s: float, gms: GmsParams | None = None,
    ) -> Context:  # fmt: skip
        """A context from the samples and their precomputed path quantities."""
        return cls(
            t, x, v, a, f,
            direction=path[:, _OUT_DIR],
            distance_since_reversal_m=path[:, _OUT_S_REV],
            dwell_s=path[:, _OUT_DWELL],
            distance_since_start_m=path[:, _OUT_S_START],
            moving=path[:, _OUT_MOVING],
            resting=path[:, _OUT_RESTING],
            elapsed_s=path[:, _OUT_ELAPSED],
            sample_time_s=sample_time_s,
            gms=gms,
        )  # fmt: skip
