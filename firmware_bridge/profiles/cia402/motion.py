"""Motion on a CiA 402 bus: the axis a drive hosts, the NC's part program, what is seen.

- :class:`DriveAxis`: what a drive does with its motion each bus cycle (cyclic
  synchronous position): the simulated machine's axis implements it, a real drive
  has its own.
- :class:`NcProgram`: the NC's side of one motion: the CiA 402 enable sequence on the
  controlword, then one target position per SYNC, then the axis held and disabled. The
  NC of ``gms-comp machine --nc`` sends it, and so do ``record`` and ``commission`` when
  they drive the axis themselves.
- :class:`Observed`: the latest motion seen on the bus (the NC's RPDO1 as it passes,
  the drive's TPDO1/TPDO2), for a compensator that follows the machine and a recorder.

Positions travel in increments of the drive's position unit (object 0x2010, in
picometres), velocities in increments per second, currents in per mille of the rated
current 0x6075.
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import can

from firmware_bridge.profiles.cia402.codec import MOTION_TPDO, NC_RPDO, Cia402Codec
from firmware_bridge.profiles.cia402.statemachine import (
    DISABLE_VOLTAGE,
    ENABLE_SEQUENCE,
    SHUTDOWN,
    PowerState,
    state_of,
)

PICOMETRE = 1e-12
ENABLE_WAIT_CYCLES = 500
"""How long the NC waits for each step of the enable sequence (and for the first position
actual): 0.5 s at 1 kHz, as a drive releasing its brake may take; 50 cycles failed now and
then against a machine process just started on a loaded host."""


class AxisSample(Protocol):
    """What a drive reads off its axis at the end of a bus cycle (SI units)."""

    @property
    def position_m(self) -> float:
        """The encoder's reading."""
        ...

    @property
    def velocity_m_s(self) -> float:
        """The drive's velocity estimate."""
        ...

    @property
    def current_A(self) -> float:
        """The measured motor current."""
        ...

    @property
    def following_error_m(self) -> float:
        """Target less the encoder's reading."""
        ...


class DriveAxis(Protocol):
    """The motion a drive hosts, one bus cycle per :meth:`cycle` (CSP, 0x6060 = 8)."""

    max_following_error_m: float
    force_constant_N_per_A: float  # the motor's, as the drive knows it (0x2011)
    servo_period_s: float  # the drive's servo cycle, several per bus cycle

    def cycle(
        self,
        target_position_m: float,
        torque_offset_A: float,
        enabled: bool,
        in_drive: Callable[[float, float], float] | None = None,
    ) -> AxisSample:
        """Follow the target with the feedforward added (held in place when not enabled);
        ``in_drive(position, velocity)`` adds the drive's own feedforward each servo cycle,
        stepped on the position command (the target interpolated) and its speed."""
        ...


class Phase(enum.Enum):
    """Where an :class:`NcProgram` is."""

    ENABLING = "enabling"
    MOVING = "moving"
    DISABLING = "disabling"
    DONE = "done"
    FAILED = "failed"


@dataclass
class NcProgram:
    """One motion of the NC: enable, the targets one per SYNC, hold, disable.

    Parameters
    ----------
    targets_m
        Target positions, one per bus cycle, relative to the first: the motion starts
        where the axis stands when the drive is enabled (``origin_m``).
    unit_m
        The drive's position unit (0x2010).
    hold_cycles
        Cycles the last target is held before the drive is disabled.
    repeat
        Run the targets back and forth until stopped (a machine working through its part
        program again and again) instead of disabling after the hold.
    """

    targets_m: Sequence[float]
    unit_m: float
    hold_cycles: int = 100
    origin_m: float = 0.0
    repeat: bool = False
    phase: Phase = Phase.ENABLING
    index: int = 0  # the target sent last
    _step: int = 0  # which command of the enable sequence
    _waited: int = 0
    _held: int = 0
    _placed: bool = False

    def start_at(self, position_m: float | None) -> None:
        """Where the axis stands (its first position actual seen): the origin, fixed then
        (the targets sent while enabling hold it still)."""
        if not self._placed and position_m is not None:
            self.origin_m, self._placed, self._waited = position_m, True, 0

    def target_at(self, index: int) -> float:
        """Target ``index`` (clipped to the program), in absolute position."""
        i = min(max(index, 0), len(self.targets_m) - 1)
        return self.origin_m + float(self.targets_m[i]) - float(self.targets_m[0])

    def rpdo(self, codec: Cia402Codec, seen: PowerState | None) -> can.Message | None:
        """The RPDO1 of this cycle, given the state the drive showed last (None: unknown);
        None before the drive has reported its position (the origin) and once the program
        is over."""
        if not self._placed:
            self._waited += 1
            if self._waited > ENABLE_WAIT_CYCLES:
                self.phase = Phase.FAILED  # a drive that does not report its position
            return None
        controlword, target = self._next(seen)
        if controlword is None:
            return None
        data = NC_RPDO.packing.pack(controlword, round(target / self.unit_m))
        return can.Message(arbitration_id=codec.nc_cob_id, data=data, is_extended_id=False)

    def _next(self, seen: PowerState | None) -> tuple[int | None, float]:
        start = self.target_at(0)
        if self.phase is Phase.ENABLING:
            wanted = (PowerState.READY_TO_SWITCH_ON, PowerState.SWITCHED_ON,
                      PowerState.OPERATION_ENABLED)[self._step]  # fmt: skip
            if seen is wanted:
                self._step, self._waited = self._step + 1, 0
                if self._step == len(ENABLE_SEQUENCE):
                    self.phase = Phase.MOVING
                    return ENABLE_SEQUENCE[-1], start
            self._waited += 1
            if self._waited > ENABLE_WAIT_CYCLES:
                self.phase = Phase.FAILED
                return DISABLE_VOLTAGE, start
            return ENABLE_SEQUENCE[self._step], start
        if self.phase is Phase.MOVING:
            if seen is not None and seen is not PowerState.OPERATION_ENABLED:
                self.phase = Phase.FAILED  # the drive left operation (a fault)
                return DISABLE_VOLTAGE, self.target_at(self.index)
            if self.index + 1 < len(self.targets_m):
                self.index += 1
            else:
                self._held += 1
                if self._held >= self.hold_cycles and self.repeat:  # back the other way
                    self.targets_m, self.index, self._held = self._reversed(), 0, 0
                elif self._held >= self.hold_cycles:
                    self.phase = Phase.DISABLING
            return ENABLE_SEQUENCE[-1], self.target_at(self.index)
        if self.phase is Phase.DISABLING:
            self.phase = Phase.DONE
            return SHUTDOWN, self.target_at(self.index)
        return None, 0.0

    def _reversed(self) -> list[float]:
        """The targets run backwards from where the axis stands (origin kept continuous)."""
        end = self.target_at(len(self.targets_m) - 1)
        backwards = [float(t) for t in reversed(self.targets_m)]
        self.origin_m = end
        return backwards

    def stop(self) -> None:
        """End the program early: the next RPDO1 disables the drive (shutdown)."""
        if self.phase in (Phase.ENABLING, Phase.MOVING):
            self.phase = Phase.DISABLING

    @property
    def moving(self) -> bool:
        """The drive is following the targets."""
        return self.phase is Phase.MOVING


@dataclass
class Observed:
    """The latest motion seen on the bus, in SI units; None where nothing came yet."""

    unit_m: float
    rated_current_A: float
    target_m: float | None = None  # the NC's RPDO1
    controlword: int | None = None
    statusword: int | None = None  # TPDO1
    current_A: float | None = None
    position_m: float | None = None  # TPDO2
    velocity_m_s: float | None = None
    counts: dict[str, int] = field(default_factory=lambda: {"nc": 0, "status": 0, "motion": 0})

    @property
    def state(self) -> PowerState | None:
        """The drive's state by its last statusword."""
        return None if self.statusword is None else state_of(self.statusword)

    def take(self, codec: Cia402Codec, msg: can.Message) -> str | None:
        """Note one frame if it is the NC's RPDO1 or a TPDO; which one it was."""
        data = bytes(msg.data)
        cob_id = msg.arbitration_id
        if cob_id == codec.nc_cob_id and len(data) == NC_RPDO.size:
            self.controlword, target = NC_RPDO.packing.unpack(data)
            self.target_m = target * self.unit_m
            kind = "nc"
        elif cob_id == codec.status_cob_id:
            report = codec.unpack_status(data)
            if report is None:
                return None
            self.statusword = report.statusword
            self.current_A = report.current_raw * self.rated_current_A / 1000
            kind = "status"
        elif cob_id == codec.motion_cob_id and len(data) == MOTION_TPDO.size:
            position, velocity = MOTION_TPDO.packing.unpack(data)
            self.position_m, self.velocity_m_s = position * self.unit_m, velocity * self.unit_m
            kind = "motion"
        else:
            return None
        self.counts[kind] += 1
        return kind
