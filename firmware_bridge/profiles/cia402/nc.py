"""The NC as SYNC master, for a compensator that follows SYNC (``sync_master = false``)."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable

import can

from firmware_bridge.profiles.cia402.codec import Cia402Codec


class SyncProducer:
    """The NC as SYNC master: one SYNC per cycle on the wall clock.

    Used when the compensator follows SYNC (``sync_master = false``); in a
    real installation the NC or another master produces it.
    """

    def __init__(self, bus: can.BusABC, codec: Cia402Codec, period_s: float) -> None:
        self.bus = bus
        self.frame = codec.sync_frame()
        self.period_s = period_s
        self.sent = 0

    def send(self) -> None:
        """Send one SYNC now."""
        self.bus.send(self.frame)
        self.sent += 1

    def run(self, stop: threading.Event, clock: Callable[[], float] = time.perf_counter) -> None:
        """Send SYNC on a fixed grid until ``stop`` is set (call in a thread or process).

        A late wake-up sends one SYNC and rejoins the grid, as a master's timer would.
        """
        next_s = clock()
        while not stop.is_set():
            remaining = next_s - clock()
            if remaining > 0:
                time.sleep(remaining)
            self.send()
            missed = max(0, math.floor((clock() - next_s) / self.period_s))
            next_s += (1 + missed) * self.period_s
