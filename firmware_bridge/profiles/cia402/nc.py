"""The NC as SYNC master: for a compensator that follows SYNC (``sync_master = false``),
and with a part program (:class:`MotionNc`) for the simulated machine."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable

import can

from firmware_bridge.profiles.base import SYNC_COUNTER_OVERFLOW
from firmware_bridge.profiles.cia402.codec import Cia402Codec
from firmware_bridge.profiles.cia402.motion import NcProgram, Observed


class SyncProducer:
    """The NC as SYNC master: one SYNC per cycle on the wall clock, with the SYNC counter.

    Used when the compensator follows SYNC (``sync_master = false``); in a
    real installation the NC or another master produces it. The counter
    (1..240, CiA 301 0x1019) numbers the grid's slots, so a SYNC sent late
    still says which slot it belongs to, and a skipped one shows as a gap.
    """

    slips = False
    """Whether a late wake-up moves the grid instead of skipping its slots."""

    def __init__(self, bus: can.BusABC, codec: Cia402Codec, period_s: float) -> None:
        self.bus = bus
        self.codec = codec
        self.period_s = period_s
        self.sent = 0
        self.slot = 0  # the grid slot of the next SYNC
        self.slipped = 0  # periods the grid moved by (a producer that slips)

    def send(self) -> None:
        """Send the SYNC of the current slot now and move to the next slot."""
        self.bus.send(self.codec.sync_frame(self.slot % SYNC_COUNTER_OVERFLOW + 1))
        self.sent += 1
        self.slot += 1

    def run(self, stop: threading.Event, clock: Callable[[], float] = time.perf_counter) -> None:
        """Send SYNC on a fixed grid until ``stop`` is set (call in a thread or process).

        A late wake-up sends one SYNC, numbered by the slot it is sent in (the
        slots already over are skipped, never sent late under their own number),
        and rejoins the grid, as a master's timer would; a producer that
        :attr:`slips` sends the next slot late instead and moves the grid by the
        periods lost.
        """
        next_s = clock()
        while not stop.is_set():
            remaining = next_s - clock()
            if remaining > 0:
                time.sleep(remaining)
            over = max(0, math.floor((clock() - next_s) / self.period_s))
            self.slot += 0 if self.slips else over
            next_s += over * self.period_s
            self.send()
            missed = max(0, math.floor((clock() - next_s) / self.period_s))
            self.slot += 0 if self.slips else missed
            self.slipped += (over + missed) if self.slips else 0
            next_s += (1 + missed) * self.period_s


class MotionNc(SyncProducer):
    """The NC with a part program: each cycle its RPDO1 (controlword, target), then SYNC.

    It reads the drive's statusword from the bus to step through the enable sequence
    (:class:`~firmware_bridge.profiles.cia402.motion.NcProgram`); after the program it
    keeps producing SYNC, the drive disabled. Its program's time is its count of SYNCs,
    one target each, so it :attr:`slips` (a drive locked to SYNC moves one cycle per
    SYNC: a skipped number would be a gap in a recording where the axis had none).
    """

    slips = True

    def __init__(
        self,
        bus: can.BusABC,
        codec: Cia402Codec,
        period_s: float,
        program: NcProgram,
        observed: Observed,
    ) -> None:
        super().__init__(bus, codec, period_s)
        self.program = program
        self.observed = observed

    def send(self) -> None:
        """Read what the drive said, send this cycle's RPDO1 (if any), then SYNC."""
        while (msg := self.bus.recv(timeout=0.0)) is not None:
            self.observed.take(self.codec, msg)
        self.program.start_at(self.observed.position_m)
        rpdo = self.program.rpdo(self.codec, self.observed.state)
        if rpdo is not None:
            self.bus.send(rpdo)
        super().send()
