"""Friction truths as numba data: the packs the compiled closed loop steps.

A truth pack ``(kind, scale, ball, gms)`` holds the transient ball set
(:mod:`gms_comp.physics.transient`'s streaming kernel), a GMS model, or no friction, in
one tuple layout (unused parts are empty placeholders), so that one compiled loop
serves every truth; ``scale[0]`` multiplies the force (identical ball sets in
parallel; a one-element array, so that a friction level that drifts is that scale
changed between cycles). The arrays are the models' own: stepping a pack advances the model
object. (The compensators' models are the strategies' own compiled steps,
:mod:`sim.strategies`.)
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np

from gms_comp import gms as gms_kernel
from gms_comp.gms import GmsStream
from gms_comp.physics import transient
from gms_comp.physics.transient import BallSetFriction

ZERO, BALL_SET, GMS = range(3)

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


def truth_pack(friction: object, scale: float = 1.0) -> Pack | None:
    """The pack of a friction truth, or None if it has no compiled form."""
    if isinstance(friction, BallSetFriction):
        return (BALL_SET, np.array([scale]), friction.streaming_kernel, _NO_GMS)
    if isinstance(friction, GmsStream):
        return (GMS, np.array([scale]), _NO_BALL, friction.kernel)
    return None


def zero_truth() -> Pack:
    """The pack of a frictionless axis."""
    return (ZERO, np.zeros(1), _NO_BALL, _NO_GMS)


@numba.njit(cache=True)
def truth_force(truth: Pack, position_m: float, velocity_m_s: float) -> float:  # pragma: no cover
    """Resisting force of a truth pack (``F v >= 0`` in steady sliding)."""
    kind, scale, ball, g = truth
    if kind == BALL_SET:
        return scale[0] * transient.step_streaming(ball, position_m, velocity_m_s)
    if kind == GMS:
        return scale[0] * gms_kernel.stream_step(g, position_m, velocity_m_s)
    return 0.0
