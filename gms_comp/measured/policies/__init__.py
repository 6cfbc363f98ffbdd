"""The diagnosis policy of every catalogue effect, registered once beside the runtime's
catalogue (:data:`POLICIES`, the same names as :data:`gms_comp.runtime.effects.CATALOGUE`).

Adding an effect to the diagnosis: its runtime module (the form the compensator runs),
one module here with a :class:`~.base.Policy` subclass (its bounds, grids, what it trades
against), and one line in each registry. :mod:`.base` is the interface.
"""

from __future__ import annotations

from gms_comp.measured.policies.base import Policy, Shape
from gms_comp.measured.policies.direction_asymmetry import DirectionAsymmetryPolicy
from gms_comp.measured.policies.drift import DriftPolicy
from gms_comp.measured.policies.drive_lag import DriveLagPolicy
from gms_comp.measured.policies.dwell_time import DwellTimePolicy
from gms_comp.measured.policies.inertia import InertiaPolicy
from gms_comp.measured.policies.leftover import Leftover
from gms_comp.measured.policies.offset import OffsetPolicy
from gms_comp.measured.policies.position_ripple import PositionRipplePolicy
from gms_comp.measured.policies.reversal_transient import ReversalTransientPolicy
from gms_comp.measured.policies.sensor_lowpass import SensorLowpassPolicy
from gms_comp.measured.policies.stribeck import StribeckPolicy
from gms_comp.measured.policies.viscous import ViscousPolicy
from gms_comp.runtime import effects as fx

POLICIES: dict[str, type[Policy]] = {
    p.effect.name: p
    for p in (
        ViscousPolicy,
        StribeckPolicy,
        DwellTimePolicy,
        PositionRipplePolicy,
        OffsetPolicy,
        ReversalTransientPolicy,
        DriftPolicy,
        InertiaPolicy,
        SensorLowpassPolicy,
        DirectionAsymmetryPolicy,
        DriveLagPolicy,
    )
}

__all__ = ["POLICIES", "Leftover", "Policy", "Shape", "policy"]


def policy(effect: type[fx.Effect] | fx.Effect) -> type[Policy]:
    """The diagnosis policy of ``effect`` (a catalogue class or an instance)."""
    return POLICIES[effect.name]
