"""The drive emulator: a simulated drive behind the same bus as a real one.

It receives the feedforward on any python-can bus, applies it to the simulated
plant's current loop (:attr:`DriveEmulator.applied_current_A`, one value per
drive cycle), and reports its status. The profile decides how frames are
checked; :class:`~firmware_bridge.supervisor.Supervisor` decides what is applied.

Two ways to run it: :meth:`step` drains the bus and runs one drive cycle at a
given time (deterministic, used by the simulated closed loop and the tests), or
:meth:`run` does so on its own clock in a thread, as a separate device would.

As a separate process (a drive on another node of the bus)::

    python -m firmware_bridge.emulator [CONFIG] --interface udp_multicast \
        --channel ff11::4743:4d53 [--profile e2e] [--nc-sync] [--duration S]

It prints ``ready`` once it listens, runs until ``--duration`` ends or it gets
SIGTERM/SIGINT, then prints its status as one JSON line. ``--nc-sync`` also
plays the NC as SYNC master (for a compensator with ``sync_master = false``).
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from contextlib import ExitStack
from dataclasses import replace
from pathlib import Path
from typing import Any

import can

from firmware_bridge.bus import open_bus
from firmware_bridge.profiles import PROFILES
from firmware_bridge.profiles.base import DriveSide, get_profile
from firmware_bridge.settings import CanConfig, load_can_config
from firmware_bridge.supervisor import RejectCounts, Verdict
from gms_comp.errors import BusError, GmsCompError

SYNC_HOLDOVER_S = 0.02
"""How late a SYNC may be before a drive locked to it runs cycles on its own clock (as a
PLL holds over): the Python NC and compensator on a loaded 2-core host were 4 ms late
at most in a minute at a load of 2.5, and 20-100 ms now and then at a load of 9."""


class DriveEmulator:
    """A drive receiving the feedforward of profile ``cfg.profile`` on ``bus``.

    Parameters
    ----------
    cfg
        The ``[can]`` section.
    bus
        The drive's bus handle.
    side
        The drive's side, built on ``bus`` (the simulated machine's drive hosts an
        axis); by default the profile's drive.
    """

    def __init__(self, cfg: CanConfig, bus: can.BusABC, side: DriveSide | None = None) -> None:
        self.cfg = cfg
        self.bus = bus
        self.cycle = 0
        self.applied_current_A = 0.0
        self.max_applied_current_A = 0.0
        self.applied_log: list[tuple[float, bytes]] = []
        self.frames_applied = 0
        self.output_log: list[tuple[float, float]] | None = None  # (time, A) per cycle, if set
        self.side: DriveSide = side or get_profile(cfg.profile).make_drive(cfg, bus)

    @property
    def counts(self) -> RejectCounts:
        """Received frames by verdict."""
        return self.side.counts

    def handle(self, msg: can.Message, now_s: float) -> None:
        """Take one frame received at ``now_s``."""
        self.side.handle(msg, now_s)

    def tick(self, now_s: float) -> float:
        """Run one drive cycle; returns the feedforward current applied in it."""
        out, fresh = self.side.tick(now_s, self.cycle)
        if fresh is not None:
            self.frames_applied += 1
            self.applied_log.append((now_s, fresh))
        self.cycle += 1
        self.applied_current_A = self.side.from_raw(out)
        self.max_applied_current_A = max(self.max_applied_current_A, abs(self.applied_current_A))
        if self.output_log is not None:
            self.output_log.append((now_s, self.applied_current_A))
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
        firmware running on time. A drive whose cycle is locked to SYNC (a side with
        ``cycle_sync_cob_id``, the simulated machine's) runs its cycle at each SYNC
        instead, and on its own grid only before the first SYNC and once SYNC is
        :data:`SYNC_HOLDOVER_S` overdue. ``clock`` must share the bus timestamps' epoch;
        frames without a plausible timestamp are taken as arriving now. A frame
        applies at the first drive cycle after its arrival, and only while fresh
        by its reception stamp (:meth:`DriveSide.set_real_time`).
        """
        period = self.cfg.cycle_period_s
        self.side.set_real_time(True)  # a frame applies at the drive cycle after its arrival
        sync_id: int | None = getattr(self.side, "cycle_sync_cob_id", None)
        last_sync: float | None = None

        def on_own_clock(t: float) -> bool:  # a drive locked to SYNC ticks at SYNC instead
            return sync_id is None or last_sync is None or t - last_sync > SYNC_HOLDOVER_S

        next_tick = clock()
        while not stop.is_set():
            msg = self.bus.recv(timeout=max(0.0, next_tick - clock()))
            if msg is None:
                if clock() >= next_tick:
                    if on_own_clock(next_tick):
                        self.tick(next_tick)
                    next_tick += period
                continue
            now = clock()
            arrival = msg.timestamp if abs(msg.timestamp - now) < 1.0 else now
            while next_tick <= arrival:
                if on_own_clock(next_tick):
                    self.tick(next_tick)
                next_tick += period
            self.handle(msg, arrival)
            if msg.arbitration_id == sync_id:
                last_sync = arrival
                self.tick(arrival)
                next_tick = arrival + period

    def status(self) -> dict[str, Any]:
        """Counters and state, in the units of the JSON report."""
        counts = self.counts
        return {
            "profile": self.cfg.profile,
            "state": self.side.state(),
            "frames_applied": self.frames_applied,
            "frames_rejected": counts.rejected,
            "sessions_granted": counts.counts[Verdict.GRANTED],
            "applied_current_A": self.applied_current_A,
            "max_applied_current_A": self.max_applied_current_A,
            "emcy": self.side.emcy(),
        }


def main(argv: Sequence[str] | None = None) -> int:
    """Run the drive emulator as its own process (see the module docstring)."""
    args = _parser().parse_args(argv)
    stop = threading.Event()
    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, lambda *_: stop.set())
    try:
        cfg = load_can_config(args.config)
        overrides = {
            k: v for k in ("profile", "interface", "channel") if (v := getattr(args, k)) is not None
        }
        if args.nc_sync:  # the compensator follows SYNC: its RPDOs wait for the next one
            overrides["sync_master"] = False
        cfg = replace(cfg, **overrides)
        with ExitStack() as stack:
            drive = DriveEmulator(cfg, stack.enter_context(open_bus(cfg)))
            devices = []
            if args.nc_sync:
                nc = get_profile(cfg.profile).make_nc(cfg, stack.enter_context(open_bus(cfg)))
                if nc is None:
                    raise BusError(f"--nc-sync: profile {cfg.profile} has no SYNC")
                devices.append(threading.Thread(target=nc.run, args=(stop, time.time)))
            print("ready", flush=True)
            timer = threading.Timer(args.duration, stop.set)
            for device in (timer, *devices):
                device.start()
            drive.run(stop, time.time)
            timer.cancel()
            for device in devices:
                device.join()
            status = drive.status()
    except GmsCompError as err:
        print(f"firmware_bridge.emulator: error: {err}", file=sys.stderr)
        return 2
    status["applied_payloads"] = sorted({data.hex() for _, data in drive.applied_log})
    print(json.dumps(status), flush=True)
    return 0


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m firmware_bridge.emulator",
        description="The drive emulator as a node of a CAN bus.",
    )
    p.add_argument("config", nargs="?", type=Path, help="config file (default: Table 1)")
    p.add_argument("--profile", choices=tuple(PROFILES), help="override [can] profile")
    p.add_argument("--interface", help="python-can interface")
    p.add_argument("--channel", help="python-can channel")
    p.add_argument(
        "--duration",
        type=float,
        default=60.0,
        metavar="S",
        help="stop after S seconds at the latest (60)",
    )
    p.add_argument(
        "--nc-sync", action="store_true", help="also produce SYNC, as the NC would (cia402)"
    )
    return p


if __name__ == "__main__":
    sys.exit(main())
