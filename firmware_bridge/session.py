"""A streaming session: compensator, optional fault injection, drive emulator, report.

:class:`Rig` wires the parts on any python-can interface. It runs either stepped
(one call per control cycle, the emulator stepped in the same thread: the
simulated closed loop and the tests) or in real time (:func:`run_stream`: the
control loop on the wall clock, the emulator in its own thread as a separate
device, deadline statistics).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import can
import numpy as np

from gms_comp.errors import BusError

from .busload import check_bus_load
from .emulator import DriveEmulator
from .faults import Fault, FaultyBus
from .settings import CanConfig
from .streamer import Streamer, count_unsent_applied, make_tx, profile_bus_load

FeedforwardSource = Callable[[float], float]  # time in s -> feedforward current in A


def open_bus(cfg: CanConfig) -> can.BusABC:
    """A bus handle on the configured interface and channel."""
    try:
        return can.Bus(interface=cfg.interface, channel=cfg.channel, bitrate=cfg.bitrate_bit_s)
    except (can.CanError, ImportError, OSError, ValueError) as err:
        raise BusError(f"cannot open CAN interface {cfg.interface!r} "
                       f"channel {cfg.channel!r}: {err}") from err


class Rig:
    """Streamer (through a fault injector) and drive emulator on one CAN channel."""

    def __init__(
        self, cfg: CanConfig, faults: Sequence[Fault] = (), seed: int = 0,
        log_path: str | Path | None = None,
    ) -> None:
        self.cfg = cfg
        self.tx = make_tx(cfg)
        self.bus_load = profile_bus_load(cfg, self.tx)
        check_bus_load(self.bus_load)
        self._stack = ExitStack()
        try:
            comp_bus = self._stack.enter_context(open_bus(cfg))
            drive_bus = self._stack.enter_context(open_bus(cfg))
            self.nc_bus = None if cfg.sync_master else self._stack.enter_context(open_bus(cfg))
            if log_path is not None:
                monitor = self._stack.enter_context(open_bus(cfg))
                notifier = can.Notifier(monitor, [can.Logger(str(log_path))])
                self._stack.callback(notifier.stop)
            self.faulty = FaultyBus(
                comp_bus, tuple(faults), self.tx.target_ids, self.tx.self_checked, seed
            )
            self.streamer = Streamer(cfg, self.faulty, self.tx)
            self.emulator = DriveEmulator(cfg, drive_bus)
        except BaseException:
            self._stack.close()
            raise

    def close(self) -> None:
        self._stack.close()

    def __enter__(self) -> Rig:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def send_cycle(self, cycle: int, current_A: float | None, now_s: float | None = None) -> None:
        """The compensator's part of control cycle ``cycle`` (nothing while stalled)."""
        now_s = cycle * self.cfg.cycle_period_s if now_s is None else now_s
        self.faulty.begin_cycle(cycle, now_s)
        if self.nc_bus is not None:  # the NC is the SYNC master
            self.nc_bus.send(self.tx.codec.sync_frame())  # type: ignore[attr-defined]
        if not self.faulty.stalled():
            self.streamer.cycle(cycle, current_A, now_s)

    def step(self, cycle: int, current_A: float | None) -> float:
        """Stepped mode: one control cycle and one drive cycle; the applied current."""
        self.send_cycle(cycle, current_A)
        return self.emulator.step(cycle * self.cfg.cycle_period_s)

    def report(self) -> dict[str, Any]:
        """The stream summary (timing keys are added by the real-time runner)."""
        window_s = (self.cfg.max_frame_age_cycles + 2) * self.cfg.cycle_period_s
        status = self.emulator.status()
        return {
            "profile": self.cfg.profile,
            "frames_sent": self.streamer.frames_sent,
            "frames_applied": status["frames_applied"],
            "frames_rejected": status["frames_rejected"],
            "frames_resync": status["frames_resync"],
            "stale_or_corrupt_applied": count_unsent_applied(
                self.streamer.sent_log, self.emulator.applied_log, window_s
            ),
            "send_errors": self.streamer.send_errors,
            "faults_injected": dict(self.faulty.injected),
            "bus_load": self.bus_load,
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
) -> dict[str, Any]:
    """Stream ``source`` for ``duration_s`` in real time to the emulator, then ramp down."""
    if not cfg.sync_master:
        raise BusError("real-time streaming needs [can] sync_master = true "
                       "(follower mode runs stepped, through CanFeedforwardLink)")
    with Rig(cfg, faults, seed, log_path) as rig:
        t0 = clock() + cfg.cycle_period_s

        def since_start() -> float:
            return clock() - t0

        # the drive and the audit log run on the bus timestamps' clock
        rig.streamer.send_clock = time.time
        stop = threading.Event()
        drive = threading.Thread(target=rig.emulator.run, args=(stop, time.time), daemon=True)
        drive.start()
        try:
            timing = _control_loop(rig, source, duration_s, since_start)
        finally:
            time.sleep(cfg.fallback_time_s)  # let the drive see the end of the stream
            stop.set()
            drive.join()
        return {**rig.report(), **timing}


def _control_loop(
    rig: Rig, source: FeedforwardSource, duration_s: float, clock: Callable[[], float]
) -> dict[str, Any]:
    """Cycle ``k`` is due at ``clock() == k * period``."""
    period = rig.cfg.cycle_period_s
    n_cycles = round(duration_s / period)
    loop_times: list[float] = []
    late = skipped = 0
    max_lateness = 0.0
    cycle = 0
    while cycle < n_cycles or rig.streamer.shaper.value_raw != 0:
        scheduled = cycle * period
        _sleep_until(scheduled, clock)
        stall_end = rig.faulty.stall_end(clock())
        if stall_end is not None:  # an injected controller stall blocks the loop
            _sleep_until(stall_end, clock)
        start = clock()
        rig.send_cycle(cycle, source(scheduled) if cycle < n_cycles else None, start)
        done = clock()
        loop_times.append(done - start)
        lateness = start - scheduled
        max_lateness = max(max_lateness, lateness)
        late += lateness + loop_times[-1] > period
        # a late loop does not catch up with a burst: it resumes at the current slot
        behind = int(clock() / period) - cycle
        skipped += max(0, behind - 1)
        cycle += max(1, behind)
    return {
        "cycles": cycle,
        "late_cycles": late + skipped,
        "max_lateness_s": max_lateness,
        "loop_time_p99_s": float(np.percentile(loop_times, 99)) if loop_times else 0.0,
        "loop_time_max_s": max(loop_times, default=0.0),
    }


def _sleep_until(deadline: float, clock: Callable[[], float]) -> None:
    remaining = deadline - clock()
    if remaining > 0:
        time.sleep(remaining)
