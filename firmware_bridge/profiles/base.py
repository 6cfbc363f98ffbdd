"""The small interface every CAN profile implements.

A :class:`Profile` makes the compensator's sending side (:class:`CompensatorTx`)
and the drive's receiving side (:class:`DriveSide`) for a ``[can]`` section.
The streamer, the drive emulator and the session use nothing else of a profile.
"""

from __future__ import annotations

import importlib
import random
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import can

from firmware_bridge.freshness import SESSION_IDS, DriveTime, Mode
from firmware_bridge.profiles import PROFILES
from firmware_bridge.settings import CanConfig
from firmware_bridge.supervisor import RejectCounts
from gms_comp.errors import BusError

SYNC_COUNTER_OVERFLOW = 240
"""The SYNC counter runs 1..240 (CiA 301 object 0x1019, its largest overflow value)."""


class SyncCounter:
    """SYNCs seen on the bus, whoever produced them, with the latest bus timestamp.

    A SYNC may carry the CiA 301 SYNC counter (one data byte, 1..overflow): it
    numbers the producer's time slots, late or not, which the timestamps alone
    cannot (a SYNC half a cycle late looks like the next slot's on time).
    """

    def __init__(self) -> None:
        self.seen = 0
        self.last_s = 0.0
        self.last_counter: int | None = None

    def saw(self, timestamp_s: float, data: bytes = b"") -> None:
        """Count one SYNC received at ``timestamp_s`` (bus clock), with its data bytes."""
        self.seen += 1
        self.last_s = timestamp_s
        self.last_counter = data[0] if len(data) == 1 else None


def sync_slot(
    previous: int, previous_counter: int | None, counter: int | None, slot_by_time: int
) -> int:
    """The producer's time slot of a SYNC, after the one of slot ``previous``.

    Parameters
    ----------
    previous
        Slot of the previous SYNC answered.
    previous_counter, counter
        SYNC counters of the previous and this SYNC (None if the SYNC has none).
    slot_by_time
        The slot its timestamp suggests (time since the first SYNC over the period,
        rounded): ambiguous by one for a SYNC sent half a cycle late or more.

    Returns
    -------
    int
        With counters, ``previous`` plus the counter's advance, the whole
        wraps of the counter taken from the time; without, ``slot_by_time``.
        Never ``previous`` or before.
    """
    if counter is None or previous_counter is None:
        return max(previous + 1, slot_by_time)
    advance = (counter - previous_counter) % SYNC_COUNTER_OVERFLOW
    wraps = round((slot_by_time - previous - advance) / SYNC_COUNTER_OVERFLOW)
    return max(previous + 1, previous + advance + SYNC_COUNTER_OVERFLOW * max(wraps, 0))


def _draw_session() -> int:
    return random.SystemRandom().choice(SESSION_IDS)


@dataclass
class Claim:
    """The compensator's view of the drive's clock and of the session it holds.

    ``session`` is drawn at random per compensator; the drive grants it on request
    and announces whom it takes commands from with its cycle (:mod:`~firmware_bridge.freshness`).
    """

    time: DriveTime
    session: int = field(default_factory=_draw_session)

    @property
    def granted(self) -> bool:
        """The drive announced this compensator's session."""
        return self.time.session == self.session

    @property
    def held_by_other(self) -> int:
        """The session of another compensator the drive announced, else 0."""
        return 0 if self.time.session in (0, self.session) else self.time.session


class CompensatorTx(Protocol):
    """The compensator's side of a profile: what the streamer sends each cycle."""

    target_ids: frozenset[int]
    """Ids of the feedforward frames (what injected faults act on)."""
    exclusive_ids: frozenset[int]
    """Ids no other node may send while this compensator streams."""
    self_checked: bool
    """The feedforward frames carry their own CRC."""
    limit_raw: int
    """Largest magnitude sent, in the profile's raw unit."""
    follows_sync: bool
    """The compensator answers an NC's SYNC instead of pacing itself."""
    sync: SyncCounter | None
    """SYNCs seen, for a profile with SYNC; else None."""
    claim: Claim
    """The drive's clock and the session, as this side knows them."""

    def to_raw(self, current_A: float) -> int:
        """Current in A -> the frame's raw unit (not saturated)."""
        ...

    def feedforward(self, mode: Mode, raw: int, now_s: float) -> can.Message | None:
        """The feedforward frame sent at ``now_s``, stamped with the drive cycle it applies
        at (:meth:`DriveTime.stamp`); None while the drive's clock is unknown."""
        ...

    def extra(self, cycle: int) -> list[can.Message]:
        """The other frames due in control cycle ``cycle``, after the feedforward frame."""
        ...

    def traffic(self) -> list[tuple[int, float]]:
        """``(data bytes, frames per s)`` of every periodic frame of the profile."""
        ...

    def on_reply(self, msg: can.Message, now_s: float) -> None:
        """Take note of a frame received from the bus, handled at ``now_s`` (status,
        EMCY, heartbeat, SYNC)."""
        ...

    def report(self) -> dict[str, Any]:
        """Profile-specific keys of the stream report."""
        ...

    def stop_frames(self) -> tuple[list[can.Message], str]:
        """Frames that end a clean stream after the ramp to zero, and what they do."""
        ...


class DriveSide(Protocol):
    """The drive's side of a profile: what the emulator (or a firmware) runs."""

    @property
    def counts(self) -> RejectCounts:
        """Received frames by verdict."""
        ...

    def handle(self, msg: can.Message, now_s: float) -> None:
        """Take one frame received at ``now_s`` (its reception stamp)."""
        ...

    def set_real_time(self, real_time: bool) -> None:
        """Run on the drive's own clock, applying a frame at the cycle after its
        reception (True), or stepped, applying it in the cycle it arrives (False,
        the default): the transport of :func:`firmware_bridge.freshness.transport_cycles`."""
        ...

    def tick(self, now_s: float, cycle: int) -> tuple[int, bytes | None]:
        """Run drive cycle ``cycle`` at ``now_s``; a frame is applied only if fresh by its
        counter and, at ``now_s``, by its reception stamp (:mod:`firmware_bridge.freshness`).

        Returns
        -------
        tuple
            The raw value applied in this cycle, and the payload of the frame
            freshly applied in it (None if the value is held or ramping).
        """
        ...

    def from_raw(self, raw: int) -> float:
        """Raw unit -> current in A."""
        ...

    def state(self) -> str:
        """The drive's state, for the report."""
        ...

    def emcy(self) -> list[str]:
        """Emergency codes sent so far, as ``0xNNNN``."""
        ...


class Device(Protocol):
    """Something that runs on its own clock in a thread (an NC producing SYNC)."""

    def send(self) -> None:
        """Send one period's frame now (stepped use)."""
        ...

    def run(self, stop: threading.Event, clock: Callable[[], float]) -> None:
        """Run until ``stop`` is set."""
        ...


class Profile(Protocol):
    """One way of carrying the feedforward to a drive."""

    name: str

    def make_tx(self, cfg: CanConfig) -> CompensatorTx:
        """The compensator's sending side."""
        ...

    def make_drive(self, cfg: CanConfig, bus: can.BusABC) -> DriveSide:
        """The drive's receiving side, on ``bus``."""
        ...

    def make_nc(self, cfg: CanConfig, bus: can.BusABC) -> Device | None:
        """The NC's SYNC producer for a compensator that follows SYNC, else None."""
        ...


def get_profile(name: str) -> Profile:
    """The registered profile ``name``.

    Parameters
    ----------
    name
        A key of :data:`firmware_bridge.profiles.PROFILES` (``[can] profile``).

    Returns
    -------
    Profile
        The ``PROFILE`` object of the profile's module.

    Raises
    ------
    BusError
        If no profile of that name is registered.
    """
    module = PROFILES.get(name)
    if module is None:
        raise BusError(f"unknown CAN profile {name!r} (known: {', '.join(PROFILES)})")
    profile: Profile = importlib.import_module(module).PROFILE
    return profile
