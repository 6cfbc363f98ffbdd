"""Friction models as numba data: the packs the compiled closed loop steps.

A pack is a tuple of a model's parameter and state arrays with a ``kind``
tag, the same tuple layout for every kind (unused parts are empty
placeholders), so that one compiled loop serves every truth and every
compensator. The arrays are the models' own: stepping a pack advances the
model object, and the Python objects' ``step`` methods call these same
functions, so there is one implementation of each update.

- truth pack ``(kind, scale, ball, gms)``: the transient ball set
  (:mod:`gms_comp.transient`'s streaming kernel), a GMS model, or no friction;
  ``scale`` multiplies the force (identical ball sets in parallel).
- model pack ``(kind, params, state, gms)``: Coulomb+viscous, LuGre or GMS
  feedforward models (:mod:`sim.strategies`, :mod:`gms_comp.gms`).
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

from gms_comp import gms as gms_kernel
from gms_comp import transient
from gms_comp.gms import GmsStream
from gms_comp.transient import BallSetFriction

ZERO, BALL_SET, GMS, COULOMB_VISCOUS, LUGRE = range(5)

Pack = tuple[Any, ...]


_NO_GMS = GmsStream(gms_kernel.GmsParams(np.ones(1), np.zeros(1))).kernel
_NO_BALL = (
    np.zeros(5),
    np.zeros((1, 1, 1)),
    np.zeros((1, 1, 2), dtype=np.int64),
    np.zeros((1, 1, 5)),
    np.zeros((1, 2)),
    np.zeros(3),
)
_NO_ARRAY = np.zeros(1)


def truth_pack(friction: object, scale: float = 1.0) -> Pack | None:
    """The pack of a friction truth, or None if it has no compiled form."""
    if isinstance(friction, BallSetFriction):
        return (BALL_SET, scale, friction.streaming_kernel, _NO_GMS)
    if isinstance(friction, GmsStream):
        return (GMS, scale, _NO_BALL, friction.kernel)
    return None


def zero_truth() -> Pack:
    """The pack of a frictionless axis."""
    return (ZERO, 0.0, _NO_BALL, _NO_GMS)


def model_pack(kind: int, params: np.ndarray, state: np.ndarray = _NO_ARRAY) -> Pack:
    """The pack of a non-GMS feedforward model."""
    return (kind, params, state, _NO_GMS)


def gms_model_pack(stream: GmsStream) -> Pack:
    """The pack of a GMS feedforward model."""
    return (GMS, _NO_ARRAY, _NO_ARRAY, stream.kernel)


@numba.njit(cache=True)
def truth_force(truth: Pack, position_m: float, velocity_m_s: float) -> float:  # pragma: no cover
    """Resisting force of a truth pack (``F v >= 0`` in steady sliding)."""
    kind, scale, ball, g = truth
    if kind == BALL_SET:
        return scale * transient.step_streaming(ball, position_m, velocity_m_s)
    if kind == GMS:
        return scale * gms_kernel.stream_step(g, position_m, velocity_m_s)
    return 0.0


@numba.njit(cache=True)
def model_force(model: Pack, position_m: float, velocity_m_s: float) -> float:  # pragma: no cover
    """Force of a feedforward model pack (resisting sign).

    Coulomb+viscous ``params = [F_c, b, v_band]``: ``F_c sat(v / v_band) + b v``.
    LuGre ``params = [F_c, sigma0, b]``, ``state = [z, last position]`` (NaN: none
    yet): ``dz/dx = 1 - sigma0 z sgn(dx) / F_c`` solved exactly over the step.
    """
    kind, p, state, g = model
    if kind == COULOMB_VISCOUS:
        ramp = min(max(velocity_m_s / p[2], -1.0), 1.0)
        return p[0] * ramp + p[1] * velocity_m_s
    if kind == LUGRE:
        dx = 0.0 if math.isnan(state[1]) else position_m - state[1]
        state[1] = position_m
        if dx != 0.0:
            z_ss = math.copysign(p[0] / p[1], dx)
            state[0] = z_ss + (state[0] - z_ss) * math.exp(-p[1] * abs(dx) / p[0])
        return p[1] * state[0] + p[2] * velocity_m_s
    if kind == GMS:
        return gms_kernel.stream_step(g, position_m, velocity_m_s)
    return 0.0
