"""Transient friction of the ball set: the bristle field conveyed through each contact.

Seed section 3.4 read as a locomotive multi-bristle model (its refs [16-18]):
every stripe y_j of a contact is a row of bristles fixed to the raceway
surface, spaced h_j = 2 a(y_j) / N. As the contact rolls by ds (rolling
distance = ``rolling_distance_per_travel`` x carriage travel) the window
|s - m| < a(y_j) moves over the row. A bristle that enters starts at u = 0 at
the leading edge; every bristle in contact gains xi(y_j) ds and is clipped at
+-u_max(y_j) (the play operator, exact for any monotone step); a bristle that
leaves is reset. Its traction is k_q u, or C_v k_q u while it slips (saturated,
pushed outwards, carriage moving). At rest a saturated bristle carries the
stick limit f_max, so the force falls by C_v at a stop.

Sign: the returned force is the resisting force F of the ball set on the
drive, F v >= 0 in steady sliding: positive while the carriage moves in +x
(the force the drive must supply). Each stripe counts as resisting in the
direction of its own slip, F = sum_j sign(xi_j) f_j, which in steady sliding is
the sum of |F| that docs/model.md adopts from the spec.

The stripes sit at the Gauss nodes of the four areas of Eq. (14) at the
steady rolling lines, so the transient field relaxes onto the steady model of
:mod:`gms_comp.physics.ball_model`. Balls of equal load see the same history and
share one field.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from gms_comp.arrays import FloatArray
from gms_comp.physics.ball_model import area_nodes, steady_state, stripe_model
from gms_comp.physics.config import BallConfig

# Columns of the per-stripe parameter array.
_WEIGHT, _HALF, _XI, _UMAX, _SPACING = range(5)
# Columns of the per-group array.
_COUNT, _KQ = range(2)
# Relative tolerance for "a bristle sits on its slip limit".
_SATURATED = 1.0 - 1e-9


@numba.njit(cache=True)
def _place(s: float, lohi: np.ndarray, stripes: np.ndarray) -> None:  # pragma: no cover
    """Set the in-contact bristle range of every stripe for rolling position ``s``."""
    for g in range(stripes.shape[0]):
        for j in range(stripes.shape[1]):
            a = stripes[g, j, _HALF]
            h = stripes[g, j, _SPACING]
            lohi[g, j, 0] = math.ceil((s - a) / h)
            lohi[g, j, 1] = math.floor((s + a) / h)


@numba.njit(cache=True)
def _fresh_ramp(
    kq: float, xi: float, umax: float, t: float, slip: float
) -> float:  # pragma: no cover
    """Integral of |traction| over the first ``t`` of rolling behind the leading edge.

    Bristles that entered during the current run hold u = |xi| t' clipped at
    u_max; saturated ones carry ``slip`` times the stick traction.
    """
    c = abs(xi)
    if c * t <= umax:
        return 0.5 * kq * c * t * t
    reach = umax / c
    return 0.5 * kq * umax * reach + slip * kq * umax * (t - reach)


@numba.njit(cache=True)
def _unloaded_ramp(
    kq: float, xi: float, umax: float, back: float, t: float, slip: float
) -> float:  # pragma: no cover
    """Integral of traction over the first ``t`` behind a trailing edge, ``back`` after a reversal.

    The bristles there entered in the previous run: |u| = |xi| (t' + back) up
    to u_max, then unloaded by |xi| back; in the previous run's sign. Those
    driven through to -u_max slip in the new direction (``slip``).
    """
    c = abs(xi)
    if c == 0.0:
        return 0.0
    ramp = min(max(umax / c - back, 0.0), t)
    level = umax - c * back
    if level <= -umax:
        level = -umax * slip
    return 0.5 * kq * c * ramp * ramp + kq * level * (t - ramp)


@numba.njit(cache=True)
def _advance(
    state: np.ndarray,
    s_new: float,
    moving: float,
    u: np.ndarray,
    lohi: np.ndarray,
    stripes: np.ndarray,
    groups: np.ndarray,
    slip_factor: float,
) -> float:  # pragma: no cover
    """Convey the fields to rolling position ``s_new`` (monotone step); return the force.

    ``state`` holds [s, started, direction of the current run, its rolling
    length, the length of the run before]. ``moving`` is the carriage's direction (+1, -1)
    or 0 at rest; it decides whether saturated bristles slip (C_v f_max) or
    hold the stick limit f_max.
    """
    ds = s_new - state[0]
    if ds != 0.0:
        direction = 1.0 if ds > 0.0 else -1.0
        if direction == state[2]:
            state[3] += abs(ds)
        else:
            state[4] = state[3]
            state[3] = abs(ds)
        state[2] = direction
    state[0] = s_new
    direction, run, previous_run = state[2], state[3], state[4]
    ring = u.shape[2]
    total = 0.0
    for g in range(stripes.shape[0]):
        kq = groups[g, _KQ]
        group_force = 0.0
        for j in range(stripes.shape[1]):
            a = stripes[g, j, _HALF]
            h = stripes[g, j, _SPACING]
            xi = stripes[g, j, _XI]
            umax = stripes[g, j, _UMAX]
            old_lo, old_hi = lohi[g, j, 0], lohi[g, j, 1]
            new_lo = math.ceil((s_new - a) / h)
            new_hi = math.floor((s_new + a) / h)
            for i in range(old_lo, min(old_hi, new_lo - 1) + 1):
                u[g, j, i % ring] = 0.0  # left the contact: relaxed
            for i in range(max(old_lo, new_hi + 1), old_hi + 1):
                u[g, j, i % ring] = 0.0
            push = moving if xi > 0.0 else -moving  # saturated u of this sign slips
            limit = umax * _SATURATED
            step = xi * ds
            k = new_lo % ring
            total_u = 0.0  # sum of the nodes' effective displacement (traction / k_q)
            first = 0.0
            value = 0.0
            for i in range(new_lo, new_hi + 1):
                if old_lo <= i <= old_hi:
                    value = u[g, j, k] + step
                else:  # entered at the leading edge during this step
                    value = xi * direction * (a + direction * (s_new - i * h))
                value = min(max(value, -umax), umax)
                u[g, j, k] = value
                if value * push >= limit:
                    value *= slip_factor
                total_u += value
                if i == new_lo:
                    first = value
                k += 1
                if k == ring:
                    k = 0
            # Trapezoid over the nodes.
            previous = kq * value
            first *= kq
            stripe = h * (kq * total_u - 0.5 * (first + previous))
            # Gaps between the end nodes and the edges. Leading: the ramp of the
            # bristles that entered in this run, then the end node's value. Trailing:
            # the previous run's ramp, unloaded since the reversal, when that run was
            # long enough to have laid it; otherwise the end node's value.
            low_gap = new_lo * h - (s_new - a)
            high_gap = s_new + a - new_hi * h
            if direction > 0.0:
                lead_gap, lead_node, trail_gap, trail_node = high_gap, previous, low_gap, first
            else:
                lead_gap, lead_node, trail_gap, trail_node = low_gap, first, high_gap, previous
            fresh = min(run, lead_gap)
            slip = slip_factor if moving * direction > 0.0 else 1.0
            sign = 1.0 if xi > 0.0 else -1.0
            stripe += (lead_gap - fresh) * lead_node
            stripe += sign * direction * _fresh_ramp(kq, xi, umax, fresh, slip)
            if previous_run >= run + trail_gap:
                stripe -= sign * direction * _unloaded_ramp(kq, xi, umax, run, trail_gap, slip)
            else:
                stripe += trail_gap * trail_node
            lohi[g, j, 0] = new_lo
            lohi[g, j, 1] = new_hi
            group_force += stripes[g, j, _WEIGHT] * sign * stripe
        total += groups[g, _COUNT] * group_force
    return total


@numba.njit(cache=True)
def _start(
    s: float, state: np.ndarray, u: np.ndarray, lohi: np.ndarray, stripes: np.ndarray
) -> None:  # pragma: no cover
    """A relaxed field at rolling position ``s``."""
    u[:] = 0.0
    _place(s, lohi, stripes)
    state[0] = s
    state[1] = 1.0
    state[2] = 1.0
    state[3] = 0.0
    state[4] = 0.0


@numba.njit(cache=True)
def _run(
    s: np.ndarray,
    moving: np.ndarray,
    state: np.ndarray,
    u: np.ndarray,
    lohi: np.ndarray,
    stripes: np.ndarray,
    groups: np.ndarray,
    slip_factor: float,
) -> np.ndarray:  # pragma: no cover
    """Force for a whole history of rolling positions, continuing from ``state``."""
    out = np.empty(s.shape[0])
    for n in range(s.shape[0]):
        if state[1] == 0.0:
            _start(s[n], state, u, lohi, stripes)
        out[n] = _advance(state, s[n], moving[n], u, lohi, stripes, groups, slip_factor)
    return out


@numba.njit(cache=True)
def _step(
    state: np.ndarray,
    s_new: float,
    moving: float,
    u: np.ndarray,
    lohi: np.ndarray,
    stripes: np.ndarray,
    groups: np.ndarray,
    slip_factor: float,
) -> float:  # pragma: no cover
    """One streaming step: the same update as :func:`_run`, without array traffic."""
    if state[1] == 0.0:
        _start(s_new, state, u, lohi, stripes)
    return _advance(state, s_new, moving, u, lohi, stripes, groups, slip_factor)


@numba.njit(cache=True)
def step_streaming(
    kernel: Any, position_m: float, velocity_m_s: float
) -> float:  # pragma: no cover
    """One streaming step of a :attr:`BallSetFriction.streaming_kernel`, in place.

    The carriage's velocity only decides moving (slipping bristles carry
    C_v f_max) against at rest (they hold f_max).
    """
    state, u, lohi, stripes, groups, consts = kernel
    slip_factor, rolling, stop_m_s = consts[0], consts[1], consts[2]
    moving = 0.0 if abs(velocity_m_s) <= stop_m_s else math.copysign(1.0, velocity_m_s)
    return _step(state, rolling * position_m, moving, u, lohi, stripes, groups, slip_factor)


class BallSetFriction:
    """Transient friction of the configured ball set (all balls, each with its own load).

    Parameters
    ----------
    cfg
        The physics config; ``cfg.model`` sets the grid (``stripes_per_area``
        Gauss stripes in each of the four areas, ``bristles_per_stripe``).

    Examples
    --------
    >>> from gms_comp.config import load_ball_config
    >>> friction = BallSetFriction(load_ball_config())
    >>> x = np.linspace(0.0, 1e-3, 200)
    >>> round(float(friction.force(x, np.full_like(x, 0.01))[-1]), 3)
    0.277
    """

    def __init__(self, cfg: BallConfig) -> None:
        loads, counts = np.unique(
            np.asarray(cfg.stand.ball_loads_N, dtype=float), return_counts=True
        )
        rows, kq = [], []
        for load in loads:
            steady = steady_state(cfg, float(load))
            model = stripe_model(cfg, float(load))
            y, w = area_nodes(model.area_bounds_m(steady.beta), cfg.model.stripes_per_area)
            half = model.contact.half_length_m(y)
            rows.append(
                np.column_stack(
                    [
                        2.0 * w,  # both halves of the ellipse
                        half,
                        model.slip_ratio(y, steady.xi0),
                        model.slip_limit_m(y),
                        2.0 * half / cfg.model.bristles_per_stripe,
                    ]
                )
            )
            kq.append(model.k_q_N_per_m3)
        self.cfg = cfg
        self.sliding_force_N = float(
            sum(
                c * steady_state(cfg, float(q)).sliding_force_N
                for q, c in zip(loads, counts, strict=True)
            )
        )
        self._stripes = np.ascontiguousarray(np.stack(rows))
        self._groups = np.column_stack([counts.astype(float), kq])
        self._slip_factor = cfg.bearing.slip_exaggeration
        self._rolling = cfg.stand.rolling_distance_per_travel
        self._stop_m_s = cfg.model.stop_velocity_m_s
        self._state = np.zeros(5)  # [s, started, run direction, run, previous run]
        self._u, self._lohi = self._fresh_fields()
        # The streaming arrays as one tuple that :func:`step_streaming` advances in
        # place; other numba kernels (the simulator's compiled loop) step the same
        # ball set through it.
        self.streaming_kernel = (
            self._state,
            self._u,
            self._lohi,
            self._stripes,
            self._groups,
            np.array([self._slip_factor, self._rolling, self._stop_m_s]),
        )

    def _fresh_fields(self) -> tuple[FloatArray, NDArray[np.int64]]:
        g, s, _ = self._stripes.shape
        ring = self.cfg.model.bristles_per_stripe + 3  # > bristles ever in contact
        return np.zeros((g, s, ring)), np.zeros((g, s, 2), dtype=np.int64)

    def _moving(self, velocity_m_s: FloatArray) -> FloatArray:
        v = np.asarray(velocity_m_s, dtype=float)
        return np.where(np.abs(v) > self._stop_m_s, np.sign(v), 0.0)

    def force(self, position_m: ArrayLike, velocity_m_s: ArrayLike) -> FloatArray:
        """Friction force (N, resisting sign) along a history, from a virgin field.

        The field starts relaxed at ``position_m[0]``; the streaming state is
        left untouched.
        """
        x = np.asarray(position_m, dtype=float)
        v = np.asarray(velocity_m_s, dtype=float)
        if x.shape != v.shape or x.ndim != 1:
            raise ValueError("position_m and velocity_m_s must be 1-D arrays of equal length")
        if x.size == 0:
            return np.empty(0)
        s = np.ascontiguousarray(self._rolling * x)
        u, lohi = self._fresh_fields()
        return np.asarray(
            _run(
                s,
                self._moving(v),
                np.zeros(5),
                u,
                lohi,
                self._stripes,
                self._groups,
                self._slip_factor,
            )
        )

    def reset(self) -> None:
        """Relax every bristle; the next :meth:`step` starts a virgin field there."""
        self._state[:] = 0.0

    def step(self, position_m: float, velocity_m_s: float) -> float:
        """Advance the streaming field to ``position_m`` and return the force (N)."""
        return float(step_streaming(self.streaming_kernel, position_m, velocity_m_s))

    def virgin_curve(self, x_m: ArrayLike) -> FloatArray:
        """Force while moving in +x versus displacement ``x_m`` (>= 0, increasing) from rest."""
        x = np.concatenate([[0.0], np.asarray(x_m, dtype=float)])
        if np.any(np.diff(x) < 0.0):
            raise ValueError("virgin_curve needs non-negative, non-decreasing displacements")
        return self.force(x, np.ones_like(x))[1:]

    def reversal_curve(self, x_m: ArrayLike) -> FloatArray:
        """Force versus displacement ``x_m`` (>= 0) after a reversal from steady sliding.

        The set first slides in -x over the widest contact (a steady field), then
        moves in +x; by Masing's rule this is twice the virgin curve for a
        Maxwell-slip model.
        """
        d = np.asarray(x_m, dtype=float)
        if np.any(np.diff(d) < 0.0) or np.any(d < 0.0):
            raise ValueError("reversal_curve needs non-negative, non-decreasing displacements")
        run_in = 2.0 * float(self._stripes[:, :, _HALF].max()) / self._rolling
        back = np.linspace(0.0, -1.01 * run_in, 3)
        x = np.concatenate([back, back[-1] + d])
        v = np.concatenate([-np.ones_like(back), np.ones_like(d)])
        return self.force(x, v)[back.size :]
