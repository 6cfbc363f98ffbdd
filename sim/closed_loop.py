"""One closed-loop run: reference -> compensator -> link -> controller -> axis.

Per servo cycle ``k``: the encoder is read, the compensator steps (on the
reference ``look_ahead`` cycles ahead, or on the measurement), its current goes
through the feedforward link, the controller adds it to its command, and the
axis advances one cycle. The following error is the reference minus the true
position at the same instant (the tool sees the true position).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from gms_comp.observer import FrictionObserver

from .controller import CascadeController
from .link import FeedforwardLink
from .plant import LinearMotorAxis
from .trajectories import Reference

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class RunResult:
    """Signals of one run, one sample per servo cycle."""

    reference: Reference
    position_m: FloatArray
    feedforward_A: FloatArray
    current_command_A: FloatArray
    friction_N: FloatArray

    @property
    def error_m(self) -> FloatArray:
        """Following error: reference minus true position."""
        return self.reference.position_m - self.position_m


def run(
    reference: Reference,
    axis: LinearMotorAxis,
    controller: CascadeController,
    link: FeedforwardLink,
    observer: FrictionObserver | None = None,
    feed: Literal["reference", "measured"] = "reference",
    look_ahead_cycles: int = 0,
) -> RunResult:
    """Run ``reference`` once from rest; ``observer=None`` means no compensation."""
    axis.reset()
    controller.reset(axis.position_m)
    if observer is not None:
        observer.reset()
    n = reference.cycles
    # Python lists: indexing numpy arrays per cycle costs more than the arithmetic.
    x_ref = reference.position_m.tolist()
    v_ref = reference.velocity_m_s.tolist()
    a_ref = reference.acceleration_m_s2.tolist()
    inertial_gain = axis.cfg.moving_mass_kg / axis.cfg.force_constant_N_per_A
    lead = controller.acceleration_lead_cycles
    position, ff, command, friction = ([0.0] * n for _ in range(4))
    measured = axis.measure()
    for k in range(n):
        position[k] = axis.position_m
        wanted = 0.0
        if observer is not None:
            if feed == "reference":
                j = min(k + look_ahead_cycles, n - 1)
                wanted = observer.step(x_ref[j], v_ref[j])
            else:
                wanted = observer.step(measured, controller.velocity_m_s)
            observer.adapt(axis.current_A, inertial_gain * a_ref[k], v_ref[k])
        ff[k] = link.transfer(k, wanted)
        command[k] = controller.step(measured, x_ref[k], a_ref[min(k + lead, n - 1)], ff[k])
        measured = axis.step(command[k])
        friction[k] = axis.friction_force_N
    return RunResult(reference, *(np.array(s) for s in (position, ff, command, friction)))
