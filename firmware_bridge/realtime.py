"""The real-time stream: the control loop on the wall clock, the drive in its own thread.

:func:`stream_on` runs an open :class:`~firmware_bridge.session.Rig` in real time: as SYNC
master on the compensator's own clock (:func:`_control_loop`), or as SYNC follower, one
RPDO in answer to each of the NC's SYNCs (:func:`_follower_loop`); a clean stop ramps
to zero and releases the session, also on a stop request (a signal) or a Ctrl-C inside
the loop; another node on the channel ends the stream with
:class:`~firmware_bridge.streamer.ChannelTakenError`.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import can
import numpy as np

from firmware_bridge.faults import Fault
from firmware_bridge.profiles.base import SyncCounter, sync_slot
from firmware_bridge.session import FeedforwardSource, Rig
from firmware_bridge.settings import CanConfig
from firmware_bridge.streamer import ChannelTakenError

FIRST_SYNC_WAIT_S = 2.0  # a follower waits this long for the NC's first SYNC
SYNC_GONE_S = 0.5  # ... and ends the stream when SYNC stops for this long


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


Progress = Callable[[float, dict[str, Any]], None]
"""Told every second of the stream: the stream's time in s and the figures so far."""


def stream_on(
    rig: Rig,
    source: FeedforwardSource,
    duration_s: float,
    clock: Callable[[], float] = time.perf_counter,
    stop_request: threading.Event | None = None,
    progress: Progress | None = None,
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
    progress
        Told every second of the stream (the stream's time, the frames so far).

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
    rig.progress = _Ticker(rig, progress)
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


class _Ticker:
    """Calls a progress callback once per second of stream time."""

    def __init__(self, rig: Rig, progress: Progress | None) -> None:
        self.rig, self.progress, self.next_s = rig, progress, 1.0

    def __call__(self, time_s: float) -> None:
        if self.progress is None or time_s < self.next_s:
            return
        self.next_s = float(int(time_s)) + 1.0
        streamer = self.rig.streamer
        self.progress(time_s, {"frames_sent": streamer.frames_sent,
                               "inputs_missing": streamer.inputs_missing})  # fmt: skip


def _ends(cycle: int, n_cycles: int, stop_request: threading.Event) -> int:
    """The cycle the stream ends at: ``n_cycles``, or now on a stop request."""
    return min(n_cycles, cycle) if stop_request.is_set() else n_cycles


class _LoopStats:
    """Deadline statistics of the real-time loop."""

    def __init__(self, period_s: float) -> None:
        self.period_s = period_s
        self.loop_times: list[float] = []
        self.late = 0
        self.slipped = 0  # periods a late SYNC master's schedule moved by
        self.unanswered = 0  # SYNCs a late follower did not answer
        self.max_lateness = 0.0
        self.sync_to_sent: list[float] = []

    def record(self, lateness_s: float, loop_time_s: float) -> None:
        """One cycle that started ``lateness_s`` after its due time."""
        self.loop_times.append(loop_time_s)
        self.max_lateness = max(self.max_lateness, lateness_s)
        self.late += lateness_s + loop_time_s > self.period_s

    def answered(self, sync_to_sent_s: float) -> None:
        """A follower's frame went out this long after the SYNC it answers (bus clock)."""
        self.sync_to_sent.append(sync_to_sent_s)

    def summary(self, cycles: int) -> dict[str, Any]:
        times = self.loop_times
        answers = self.sync_to_sent
        follower = (
            {
                "sync_to_sent_p50_s": float(np.percentile(answers, 50)),
                "sync_to_sent_p99_s": float(np.percentile(answers, 99)),
                "sync_to_sent_max_s": max(answers),
                "answered_within_cycle": sum(a < self.period_s for a in answers) / len(answers),
            }
            if answers
            else {}
        )
        return {
            **follower,
            "cycles": cycles,
            "late_cycles": self.late + self.unanswered,
            "cycles_slipped": self.slipped,
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
        current = source(scheduled) if cycle < end else None
        rig.send_cycle(cycle, current, start, hold=cycle < end and current is None)
        stats.record(start - scheduled, since_start() - start)
        rig.progress(scheduled)
        # a late loop neither catches up with a burst nor skips the cycles it missed: it
        # slips, every cycle keeping its SYNC (the NC's program and the drive's cycles
        # stay one per SYNC; the cycles the schedule moved by are counted)
        behind = int(since_start() / period) - cycle
        if behind > 1:
            nonlocal t0
            t0 += (behind - 1) * period
            stats.slipped += behind - 1
        cycle += 1

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
        stats.unanswered += slot - cycle - 1 if cycle >= 0 else 0
        cycle = slot
        lateness = time.time() - sync.last_s
        start = clock()
        current = source(cycle * period) if cycle < end else None
        rig.send_cycle(cycle, current, cycle * period, hold=cycle < end and current is None)
        stats.record(lateness, clock() - start)
        stats.answered(time.time() - sync.last_s)
        rig.progress(cycle * period)

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
