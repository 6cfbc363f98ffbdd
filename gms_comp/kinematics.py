"""The one record of a motion's kinematics: sampled time, position, velocity, acceleration.

A measured trace's filtered kinematics (:func:`gms_comp.measured.diagnosis.motion.kinematics`),
a simulated axis' reference (:attr:`sim.trajectories.Reference.kinematics`) and what a
catalogue effect sees along a path (:meth:`gms_comp.runtime.effects.Context.of`) all
start from it.
"""

from __future__ import annotations

from dataclasses import dataclass

from gms_comp.arrays import FloatArray


@dataclass(frozen=True)
class Kinematics:
    """Position and its derivatives on one time base (arrays of one length, SI units).

    Parameters
    ----------
    time_s
        Sample times in s.
    position_m
        Position in m.
    velocity_m_s
        Velocity in m/s.
    acceleration_m_s2
        Acceleration in m/s^2.
    """

    time_s: FloatArray
    position_m: FloatArray
    velocity_m_s: FloatArray
    acceleration_m_s2: FloatArray

    def __len__(self) -> int:
        return len(self.time_s)

    def slice(self, start: int, stop: int | None = None, step: int = 1) -> Kinematics:
        """The kinematics of every ``step``-th sample from ``start`` to ``stop``."""
        s = slice(start, stop, step)
        return Kinematics(
            self.time_s[s], self.position_m[s], self.velocity_m_s[s], self.acceleration_m_s2[s]
        )
