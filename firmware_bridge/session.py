"""A streaming session: compensator, optional fault injection, drive emulator, report.

:class:`Rig` wires the parts on any python-can interface. It runs either stepped
(one call per control cycle, the emulator stepped in the same thread: the
simulated closed loop and the tests) or in real time (:func:`run_stream`: the
control loop on the wall clock, the emulator in its own thread as a separate
device, deadline statistics). In real time the drive may also be outside the
process (a real drive, or ``python -m firmware_bridge.emulator``).

Who paces the loop: as SYNC master (the default) the compensator's own clock;
as SYNC follower (cia402, ``sync_master = false``) the NC's SYNC, one RPDO in
answer to each. With the built-in emulator, a :class:`SyncProducer` plays the NC.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import can

from firmware_bridge.bus import open_bus
from firmware_bridge.busload import check_bus_load
from firmware_bridge.emulator import DriveEmulator
from firmware_bridge.faults import Fault, FaultyBus
from firmware_bridge.freshness import transport_cycles
from firmware_bridge.profiles.base import (
    CompensatorTx,
    Device,
    DriveSide,
    get_profile,
)
from firmware_bridge.settings import CanConfig
from firmware_bridge.streamer import (
    ChannelTakenError,
    Streamer,
    check_channel_free,
    count_unsent_applied,
    make_tx,
    profile_bus_load,
)
from gms_comp.errors import BusError

FeedforwardSource = Callable[[float], "float | None"]
"""Time in s -> feedforward current in A; None: no input this cycle (the motion it follows
did not arrive), so no frame is sent and the drive's timeout rules apply."""
CHANNEL_CHECK_S = 0.02  # listen this long (at least 10 cycles) for another compensator
CONNECT_CYCLES = 10  # the handshake takes 3 cycles, 4 for a SYNC follower


DriveFactory = Callable[[CanConfig, can.BusABC], DriveSide]
"""Makes the built-in drive's side on its bus (a drive hosting a simulated axis)."""


class Rig:
    """Streamer (through a fault injector) and, unless ``builtin_drive`` is false,
    the drive emulator (and the NC's SYNC, when the compensator follows it) on one
    CAN channel; ``drive`` makes the emulator's side (default: the profile's drive)."""

    def __init__(
        self,
        cfg: CanConfig,
        faults: Sequence[Fault] = (),
        seed: int = 0,
        log_path: str | Path | None = None,
        builtin_drive: bool = True,
        drive: DriveFactory | None = None,
    ) -> None:
        self.cfg = cfg
        self.tx: CompensatorTx = make_tx(cfg)
        self.bus_load = profile_bus_load(cfg, self.tx)
        check_bus_load(self.bus_load)
        self._stack = ExitStack()
        self.emulator: DriveEmulator | None = None
        self.nc_sync: Device | None = None
        self.realtime = False  # set by run_stream: the drive applies at its next cycle
        self.progress: Callable[[float], None] = lambda time_s: None  # set by stream_on
        try:
            comp_bus = self._stack.enter_context(open_bus(cfg))
            self.faulty = FaultyBus(
                comp_bus, tuple(faults), self.tx.target_ids, self.tx.self_checked, seed
            )
            self.streamer = Streamer(cfg, self.faulty, self.tx)
            listen_s = max(CHANNEL_CHECK_S, 10 * cfg.cycle_period_s)
            check_channel_free(self.streamer, listen_s, time.time)
            if log_path is not None:
                monitor = self._stack.enter_context(open_bus(cfg))
                notifier = can.Notifier(monitor, [can.Logger(str(log_path))])
                self._stack.callback(notifier.stop)
            if builtin_drive:
                bus = self._stack.enter_context(open_bus(cfg))
                self.emulator = DriveEmulator(cfg, bus, drive(cfg, bus) if drive else None)
            if builtin_drive and self.tx.follows_sync:
                nc_bus = self._stack.enter_context(open_bus(cfg))
                self.nc_sync = get_profile(cfg.profile).make_nc(cfg, nc_bus)
        except BaseException:
            self._stack.close()
            raise

    def close(self) -> None:
        """Close every bus the rig opened."""
        self._stack.close()

    def __enter__(self) -> Rig:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def drive(self) -> DriveEmulator:
        """The built-in drive emulator (an error with an external drive)."""
        if self.emulator is None:
            raise BusError("this rig streams to an external drive: no emulator to step")
        return self.emulator

    @contextlib.contextmanager
    def watching(self) -> Iterator[None]:
        """Keep the channel claim while the caller sets up: the bus is read in a thread,
        and another node's frames with this compensator's ids, or the drive held by
        another session, end the block with :class:`ChannelTakenError`."""
        stop = threading.Event()

        def watch() -> None:
            while not stop.is_set() and self.streamer.taken is None:
                msg = self.streamer.bus.recv(timeout=0.005)
                if msg is not None:
                    self.streamer.take_reply(msg, time.time())

        watcher = threading.Thread(target=watch, name="gms-comp channel watch", daemon=True)
        watcher.start()
        try:
            yield
        finally:
            stop.set()
            watcher.join()
        if self.streamer.taken is not None:
            raise ChannelTakenError(self.streamer.taken)

    def send_cycle(
        self, cycle: int, current_A: float | None, now_s: float | None = None, hold: bool = False
    ) -> None:
        """The compensator's part of control cycle ``cycle`` (nothing while stalled);
        ``current_A`` None ramps towards zero, ``hold`` sends no feedforward this cycle.

        Raises
        ------
        ChannelTakenError
            Once another node sends this compensator's frames or holds the drive.
        """
        now_s = cycle * self.cfg.cycle_period_s if now_s is None else now_s
        self.faulty.begin_cycle(cycle, now_s)
        if not self.faulty.stalled():
            self.streamer.cycle(cycle, current_A, now_s, hold)
        if self.streamer.taken is not None:
            raise ChannelTakenError(self.streamer.taken)

    def connect(self, limit_cycles: int = CONNECT_CYCLES) -> int:
        """Stepped mode: run cycles without current until the drive grants the session.

        The drive publishes its cycle, the compensator requests the session, the drive
        grants it (:mod:`firmware_bridge.freshness`); the cycle that first sees the grant
        sends a command of 0 A. Returns the next cycle's index.

        Raises
        ------
        BusError
            If the drive has not granted the session within ``limit_cycles``.
        """
        cycle = 0
        while not self.tx.claim.granted:
            if cycle >= limit_cycles:
                raise BusError(
                    f"drive node {self.cfg.drive_node_id} did not grant the feedforward "
                    f"session within {limit_cycles} cycles (is it on {self.cfg.interface} "
                    f"channel {self.cfg.channel!r}?)"
                )
            self.step(cycle, None)
            cycle += 1
        return cycle

    def step(self, cycle: int, current_A: float | None) -> float:
        """Stepped mode: one control cycle and one drive cycle; the applied current."""
        if self.nc_sync is not None:
            self.nc_sync.send()
        self.send_cycle(cycle, current_A)
        return self.drive.step(cycle * self.cfg.cycle_period_s)

    def stop(self, cycle: int, now_s: float) -> str:
        """End a clean stream (the ramp to zero is done): release the session, then the
        profile's stop frames.

        Parameters
        ----------
        cycle, now_s
            The control cycle of the release and its time on the streamer's clock.

        Returns
        -------
        str
            What the stop did, for the report.
        """
        self.faulty.begin_cycle(cycle, now_s)
        self.streamer.release(cycle, now_s)
        frames, note = self.tx.stop_frames()
        try:
            for msg in frames:
                self.streamer.bus.send(msg)
        except can.CanError:
            return "ramped to 0 A; the stop frames could not be sent (bus off)"
        return f"ramped to 0 A; {note}"

    def report(self) -> dict[str, Any]:
        """The stream summary (timing keys are added by the real-time runner).

        With an external drive, the drive-side figures are null: only the drive knows them.
        """
        report: dict[str, Any] = {
            "profile": self.cfg.profile,
            "drive": "emulator" if self.emulator is not None else "external",
            "frames_sent": self.streamer.frames_sent,
            "requests_sent": self.streamer.requests_sent,
            "undated_cycles": self.streamer.undated_cycles,
            "send_errors": self.streamer.send_errors,
            "non_finite_feedforward": self.streamer.source_faults,
            "foreign_frames": self.streamer.foreign_frames,
            "faults_injected": dict(self.faulty.injected),
            "bus_load": self.bus_load,
        }
        return {**report, **self.tx.report(), **self._drive_report()}

    def _drive_report(self) -> dict[str, Any]:
        keys = (
            "transport_cycles",
            "frames_applied",
            "frames_rejected",
            "sessions_granted",
            "stale_or_corrupt_applied",
            "max_applied_current_A",
            "drive_state",
            "emcy",
        )
        if self.emulator is None:
            return dict.fromkeys(keys)
        transport = transport_cycles(self.realtime, self.tx.follows_sync)
        status = self.emulator.status()
        return {
            "transport_cycles": transport,
            "frames_applied": status["frames_applied"],
            "frames_rejected": status["frames_rejected"],
            "sessions_granted": status["sessions_granted"],
            "stale_or_corrupt_applied": count_unsent_applied(
                self.streamer.sent_log,
                self.emulator.applied_log,
                self.cfg.cycle_period_s,
                self.cfg.max_frame_age_cycles,
                transport,
            ),
            "max_applied_current_A": status["max_applied_current_A"],
            "drive_state": status["state"],
            "emcy": status["emcy"],
        }
