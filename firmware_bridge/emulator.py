"""The drive emulator: a simulated drive behind the same bus as a real one.

It receives the feedforward on any python-can bus, applies it to the simulated
plant's current loop (:attr:`DriveEmulator.applied_current_A`, one value per
drive cycle), and reports its status. The profile decides how frames are
checked; :class:`~firmware_bridge.supervisor.Supervisor` decides what is applied.

Two ways to run it: :meth:`step` drains the bus and runs one drive cycle at a
given time (deterministic, used by the simulated closed loop and the tests), or
:meth:`run` does so on its own clock in a thread, as a separate device would.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import can
import canopen

from .cia402 import Cia402Codec, Cia402Receiver, configure_drive, load_drive_od
from .e2e import E2eCodec, E2eReceiver
from .settings import CanConfig
from .supervisor import RejectCounts, Supervisor, Verdict


class DriveEmulator:
    """A drive receiving the feedforward of profile ``cfg.profile`` on ``bus``."""

    def __init__(self, cfg: CanConfig, bus: can.BusABC) -> None:
        self.cfg = cfg
        self.bus = bus
        self.cycle = 0
        self.applied_current_A = 0.0
        self.max_applied_current_A = 0.0
        self.applied_log: list[tuple[float, bytes]] = []
        self.frames_applied = 0
        if cfg.profile == "e2e":
            self._init_e2e()
        else:
            self._init_cia402()

    def _init_e2e(self) -> None:
        codec = E2eCodec()
        limit = min(codec.limit_raw, codec.to_raw(self.cfg.max_current_A))
        supervisor = Supervisor(limit, self.cfg.timeout_cycles, self.cfg.ramp_cycles)
        self.e2e: E2eReceiver | None = E2eReceiver(codec, supervisor, self.cfg.max_frame_age_cycles)
        self.cia402: Cia402Receiver | None = None
        self._from_raw = codec.from_raw
        self.node: canopen.LocalNode | None = None

    def _init_cia402(self) -> None:
        od = load_drive_od(self.cfg.drive_node_id)
        self.node = canopen.LocalNode(self.cfg.drive_node_id, od)
        network = canopen.Network(self.bus)  # no notifier: the emulator dispatches itself
        network.add_node(self.node)
        configure_drive(self.node, self.cfg)
        codec = Cia402Codec(self.cfg, od)
        limit = min(codec.limit_raw, codec.to_raw(self.cfg.max_current_A))
        self.cia402 = Cia402Receiver(self.node, codec, self.cfg, limit)
        self.e2e = None
        self._from_raw = codec.from_raw

    @property
    def counts(self) -> RejectCounts:
        receiver = self.e2e if self.e2e is not None else self.cia402
        assert receiver is not None
        return receiver.counts

    @property
    def supervisor(self) -> Supervisor:
        receiver = self.e2e if self.e2e is not None else self.cia402
        assert receiver is not None
        return receiver.supervisor

    def handle(self, msg: can.Message, now_s: float) -> None:
        if self.e2e is not None:
            if msg.arbitration_id == self.e2e.codec.command.frame_id:
                self.e2e.on_frame(bytes(msg.data))
            elif msg.is_error_frame:
                self.e2e.counts.add(Verdict.CORRUPT)
        else:
            assert self.cia402 is not None
            self.cia402.on_message(msg, now_s)

    def tick(self, now_s: float) -> float:
        """Run one drive cycle; returns the feedforward current applied in it."""
        if self.e2e is not None:
            fresh = self.e2e.fresh_data
            self.e2e.fresh_data = None
            out = self.e2e.tick()
            if self.cycle % self.cfg.status_every_cycles == 0:
                self.bus.send(self.e2e.codec.status_frame(
                    self.cycle, out, self.e2e.state, self.counts.total_rejected
                ))
        else:
            assert self.cia402 is not None
            out = self.cia402.tick(now_s)
            fresh = self.cia402.applied_data
        if fresh is not None:
            self.frames_applied += 1
            self.applied_log.append((now_s, fresh))
        self.cycle += 1
        self.applied_current_A = self._from_raw(out)
        self.max_applied_current_A = max(self.max_applied_current_A, abs(self.applied_current_A))
        return self.applied_current_A

    def drain(self, now_s: float) -> None:
        """Handle every frame already waiting on the bus."""
        while (msg := self.bus.recv(timeout=0.0)) is not None:
            self.handle(msg, now_s)

    def step(self, now_s: float) -> float:
        """Drain the bus, then run one drive cycle at ``now_s``."""
        self.drain(now_s)
        return self.tick(now_s)

    def run(self, stop: threading.Event, clock: Callable[[], float] = time.time) -> None:
        """Run on its own clock until ``stop`` is set (call in a thread).

        Drive cycles fall on a fixed grid and each frame is handled at its bus
        arrival timestamp, so a thread the OS schedules late still behaves like
        firmware running on time. ``clock`` must share the bus timestamps' epoch;
        frames without a plausible timestamp are taken as arriving now.
        """
        period = self.cfg.cycle_period_s
        next_tick = clock()
        while not stop.is_set():
            msg = self.bus.recv(timeout=max(0.0, next_tick - clock()))
            if msg is None:
                if clock() >= next_tick:
                    self.tick(next_tick)
                    next_tick += period
                continue
            now = clock()
            arrival = msg.timestamp if abs(msg.timestamp - now) < 1.0 else now
            while next_tick <= arrival:
                self.tick(next_tick)
                next_tick += period
            self.handle(msg, arrival)

    def status(self) -> dict[str, Any]:
        """Counters and state, in the units of the JSON report."""
        state: Any
        if self.e2e is not None:
            state = ("resync", "active", "hold", "fallback")[self.e2e.state]
            emcy: list[str] = []
        else:
            assert self.cia402 is not None
            state = self.cia402.state
            emcy = [f"0x{code:04X}" for code in self.cia402.emcy_sent]
        counts = self.counts
        return {
            "state": state,
            "frames_applied": self.frames_applied,
            "frames_rejected": counts.rejected,
            "frames_resync": counts.counts[Verdict.RESYNC],
            "applied_current_A": self.applied_current_A,
            "max_applied_current_A": self.max_applied_current_A,
            "emcy": emcy,
        }
