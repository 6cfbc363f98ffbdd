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
import numpy as np

from firmware_bridge.bus import open_bus
from firmware_bridge.busload import check_bus_load
from firmware_bridge.emulator import DriveEmulator
from firmware_bridge.faults import Fault, FaultyBus
from firmware_bridge.freshness import transport_cycles
from firmware_bridge.profiles.base import (
    CompensatorTx,
    Device,
    SyncCounter,
    get_profile,
    sync_slot,
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

FeedforwardSource = Callable[[float], float]  # time in s -> feedforward current in A
CHANNEL_CHECK_S = 0.02  # listen this long (at least 10 cycles) for another compensator
FIRST_SYNC_WAIT_S = 2.0  # a follower waits this long for the NC's first SYNC
SYNC_GONE_S = 0.5  # ... and ends the stream when SYNC stops for this long
CONNECT_CYCLES = 10  # the handshake takes 3 cycles, 4 for a SYNC follower


class Rig:
    """Streamer (through a fault injector) and, unless ``builtin_drive`` is false,
    the drive emulator (and the NC's SYNC, when the compensator follows it) on one
    CAN channel."""

    def __init__(
        self,
        cfg: CanConfig,
        faults: Sequence[Fault] = (),
        seed: int = 0,
        log_path: str | Path | None = None,
        builtin_drive: bool = True,
    ) -> None:
        self.cfg = cfg
        self.tx: CompensatorTx = make_tx(cfg)
        self.bus_load = profile_bus_load(cfg, self.tx)
        check_bus_load(self.bus_load)
        self._stack = ExitStack()
        self.emulator: DriveEmulator | None = None
        self.nc_sync: Device | None = None
        self.realtime = False  # set by run_stream: the drive applies at its next cycle
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
                self.emulator = DriveEmulator(cfg, self._stack.enter_context(open_bus(cfg)))
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

    def send_cycle(self, cycle: int, current_A: float | None, now_s: float | None = None) -> None:
        """The compensator's part of control cycle ``cycle`` (nothing while stalled).

        Raises
        ------
        ChannelTakenError
            Once another node sends this compensator's frames or holds the drive.
        """
        now_s = cycle * self.cfg.cycle_period_s if now_s is None else now_s
        self.faulty.begin_cycle(cycle, now_s)
        if not self.faulty.stalled():
            self.streamer.cycle(cycle, current_A, now_s)
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


def run_stream(
    cfg: CanConfig,
    source: FeedforwardSource,
    duration_s: float,
    faults: Sequence[Fault] = (),
    seed: int = 0,
    log_path: str | Path | None = None,
    clock: Callable[[], float] = time.perf_counter,
    builtin_drive: bool = True,
) -> dict[str, Any]:
    """Stream ``source`` for ``duration_s`` in real time, then ramp down.

    The drive is the built-in emulator (in a thread), or with ``builtin_drive``
    false whatever drive is on the bus. See :func:`stream_on` for the report.
    """
    with Rig(cfg, faults, seed, log_path, builtin_drive) as rig:
        return stream_on(rig, source, duration_s, clock)


def stream_on(
    rig: Rig,
    source: FeedforwardSource,
    duration_s: float,
    clock: Callable[[], float] = time.perf_counter,
    stop_request: threading.Event | None = None,
) -> dict[str, Any]:
    """Stream ``source`` over an open ``rig`` for ``duration_s`` in real time, then ramp down.

    Parameters
    ----------
    rig
        The open rig (its channel was checked free when it opened).
    source
        Feedforward current in A as a function of the time in s.
    duration_s
        Streaming time before the ramp to zero.
    clock
        Monotonic clock of the control loop.
    stop_request
        Set (by a signal handler) to end the stream early: the same clean stop,
        ramp to zero and release. A Ctrl-C inside the loop does the same.

    Returns
    -------
    dict
        :meth:`Rig.report` plus the loop's timing statistics; ``"interrupted"`` is
        true when the stream ended on a stop request.

    Raises
    ------
    ChannelTakenError
        When another node sends this compensator's frames or holds the drive: the
        session is released first.
    """
    cfg = rig.cfg
    rig.streamer.drain_replies(time.time())  # frames queued since the rig opened are history
    # the drive and the audit log run on the bus timestamps' clock
    rig.streamer.send_clock = time.time
    rig.realtime = True
    stop_request = stop_request if stop_request is not None else threading.Event()
    stop = threading.Event()
    devices = [
        threading.Thread(target=device.run, args=(stop, time.time), daemon=True)
        for device in (rig.emulator, rig.nc_sync)
        if device is not None
    ]
    for device in devices:
        device.start()
    try:
        if rig.tx.sync is not None and rig.tx.follows_sync:
            timing = _follower_loop(rig, rig.tx.sync, source, duration_s, clock, stop_request)
        else:
            timing = _control_loop(rig, source, duration_s, clock, stop_request)
    finally:
        time.sleep(cfg.fallback_time_s)  # let the drive see the end of the stream
        stop.set()
        for device in devices:
            device.join()
    return {**rig.report(), **timing, "interrupted": stop_request.is_set()}


def _ends(cycle: int, n_cycles: int, stop_request: threading.Event) -> int:
    """The cycle the stream ends at: ``n_cycles``, or now on a stop request."""
    return min(n_cycles, cycle) if stop_request.is_set() else n_cycles


class _LoopStats:
    """Deadline statistics of the real-time loop."""

    def __init__(self, period_s: float) -> None:
        self.period_s = period_s
        self.loop_times: list[float] = []
        self.late = 0
        self.skipped = 0
        self.max_lateness = 0.0

    def record(self, lateness_s: float, loop_time_s: float) -> None:
        """One cycle that started ``lateness_s`` after its due time."""
        self.loop_times.append(loop_time_s)
        self.max_lateness = max(self.max_lateness, lateness_s)
        self.late += lateness_s + loop_time_s > self.period_s

    def summary(self, cycles: int) -> dict[str, Any]:
        times = self.loop_times
        return {
            "cycles": cycles,
            "late_cycles": self.late + self.skipped,
            "max_lateness_s": self.max_lateness,
            "loop_time_p99_s": float(np.percentile(times, 99)) if times else 0.0,
            "loop_time_max_s": max(times, default=0.0),
        }


def _control_loop(
    rig: Rig,
    source: FeedforwardSource,
    duration_s: float,
    clock: Callable[[], float],
    stop_request: threading.Event,
) -> dict[str, Any]:
    """SYNC master: cycle ``k`` is due at ``k * period`` after the start, on ``clock``."""
    period = rig.cfg.cycle_period_s
    n_cycles = round(duration_s / period)
    t0 = clock() + period

    def since_start() -> float:
        return clock() - t0

    stats = _LoopStats(period)
    cycle = 0

    def one_cycle(end: int) -> None:
        nonlocal cycle
        scheduled = cycle * period
        _sleep_until(scheduled, since_start)
        stall_end = rig.faulty.stall_end(since_start())
        if stall_end is not None:  # an injected controller stall blocks the loop
            _sleep_until(stall_end, since_start)
        start = since_start()
        rig.send_cycle(cycle, source(scheduled) if cycle < end else None, start)
        stats.record(start - scheduled, since_start() - start)
        # a late loop does not catch up with a burst: it resumes at the current slot
        behind = int(since_start() / period) - cycle
        stats.skipped += max(0, behind - 1)
        cycle += max(1, behind)

    with _released_when_taken(rig, lambda: (cycle, since_start())):
        while cycle < (end := _ends(cycle, n_cycles, stop_request)) or _ramping(rig):
            _interruptible(one_cycle, end, stop_request)
    return {**stats.summary(cycle), "end_of_stream": rig.stop(cycle, since_start())}


def _ramping(rig: Rig) -> bool:
    return rig.streamer.shaper.value_raw != 0


def _interruptible(step: Callable[[int], None], end: int, stop_request: threading.Event) -> None:
    """One cycle of a stream loop; a Ctrl-C during it asks for the clean stop instead."""
    try:
        step(end)
    except KeyboardInterrupt:
        stop_request.set()


@contextlib.contextmanager
def _released_when_taken(rig: Rig, now: Callable[[], tuple[int, float]]) -> Iterator[None]:
    """A taken channel ends the stream: the session is released before the error rises."""
    try:
        yield
    except ChannelTakenError:
        with contextlib.suppress(can.CanError):
            rig.streamer.release(*now())
        raise


def _follower_loop(
    rig: Rig,
    sync: SyncCounter,
    source: FeedforwardSource,
    duration_s: float,
    clock: Callable[[], float],
    stop_request: threading.Event,
) -> dict[str, Any]:
    """SYNC follower: one RPDO in answer to each SYNC of the NC, applied at the next.

    Cycle ``k`` is the SYNC in the ``k``-th period since the first one (the time of
    the feedforward's source), by the SYNC counter when the NC sends one (a SYNC
    sent late keeps its slot; by time alone one late by half a cycle would take the
    next slot); a loop that missed SYNCs answers only the latest (counted late).
    Lateness is the reaction time to the SYNC, on the bus timestamps' clock.
    """
    period = rig.cfg.cycle_period_s
    n_cycles = round(duration_s / period)
    stats = _LoopStats(period)
    seen = sync.seen
    cycle = -1
    first_sync_s = 0.0
    counter: int | None = None
    wait_s = FIRST_SYNC_WAIT_S
    sync_lost = False

    def one_cycle(end: int) -> None:
        nonlocal cycle, counter, seen, first_sync_s, wait_s, sync_lost
        if not _await_sync(rig, sync, seen, wait_s, clock):
            sync_lost = True  # the NC stopped: stay silent, the drive falls back
            return
        wait_s = SYNC_GONE_S
        if cycle < 0:
            first_sync_s, slot = sync.last_s, 0
        else:
            by_time = round((sync.last_s - first_sync_s) / period)
            slot = sync_slot(cycle, counter, sync.last_counter, by_time)
        counter = sync.last_counter
        seen = sync.seen
        stats.skipped += slot - cycle - 1 if cycle >= 0 else 0
        cycle = slot
        lateness = time.time() - sync.last_s
        start = clock()
        current = source(cycle * period) if cycle < end else None
        rig.send_cycle(cycle, current, cycle * period)
        stats.record(lateness, clock() - start)

    with _released_when_taken(rig, lambda: (cycle + 1, (cycle + 1) * period)):
        while not sync_lost and (
            cycle + 1 < (end := _ends(cycle + 1, n_cycles, stop_request)) or _ramping(rig)
        ):
            _interruptible(one_cycle, end, stop_request)
    timing = {**stats.summary(cycle + 1), "syncs_seen": sync.seen, "sync_lost": sync_lost}
    if not sync_lost:
        timing["end_of_stream"] = rig.stop(cycle + 1, (cycle + 1) * period)
    return timing


def _await_sync(
    rig: Rig, sync: SyncCounter, seen: int, timeout_s: float, clock: Callable[[], float]
) -> bool:
    """Handle incoming frames until a SYNC beyond the ``seen`` ones arrives, then the
    frames already waiting behind it: a loop that fell behind answers the latest SYNC
    only, not a backlog of old ones (whose frames would all be late by their counter)."""
    deadline = clock() + timeout_s
    while sync.seen == seen:
        remaining = deadline - clock()
        if remaining <= 0:
            return False
        msg = rig.faulty.recv(timeout=remaining)
        if msg is not None:
            rig.streamer.take_reply(msg, time.time())
    while (msg := rig.faulty.recv(timeout=0.0)) is not None:
        rig.streamer.take_reply(msg, time.time())
    return True


def _sleep_until(deadline: float, clock: Callable[[], float]) -> None:
    remaining = deadline - clock()
    if remaining > 0:
        time.sleep(remaining)
