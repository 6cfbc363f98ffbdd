"""The compensator following the machine on the bus: ``gms-comp run``'s production loop.

It answers each of the NC's SYNCs (cia402 as SYNC follower): it reads the target
position the NC sent the drive for that SYNC (``feed = reference``, the NC's RPDO1 seen
as it passes) or the drive's position actual (``feed = measured``, its TPDO2), steps the
GMS observer along it with its look-ahead (the position extrapolated by the last
velocity, ``look_ahead_cycles`` ahead), and sends the torque offset for the next SYNC,
under every rule of :mod:`firmware_bridge` (the session, freshness, the ramp). A SYNC
whose input did not arrive gets no frame (the drive holds, then times out), never an
extrapolated guess.
"""

from __future__ import annotations

import math
import sys
import threading
from dataclasses import dataclass, replace
from typing import Any, Literal, cast

import numpy as np

from firmware_bridge.profiles.cia402.recorder import Recorder
from firmware_bridge.profiles.cia402.tx import Cia402Tx
from firmware_bridge.realtime import stream_on
from firmware_bridge.session import Rig
from firmware_bridge.settings import CanConfig
from gms_comp.app.live.recording import reversals
from gms_comp.runtime.observer import FrictionObserver


@dataclass
class Follower:
    """The feedforward source of a follower: one observer step per SYNC answered."""

    tx: Cia402Tx
    observer: FrictionObserver | None
    feed: Literal["reference", "measured"]
    look_ahead_cycles: int
    period_s: float
    _seen: int = -1
    _last: tuple[float, float] | None = None  # the last input and its SYNC's time

    def __call__(self, t_s: float) -> float | None:
        """The feedforward for the SYNC being answered, or None if its input is missing."""
        observed = self.tx.observed
        kind = "nc" if self.feed == "reference" else "motion"
        if observed.counts[kind] == self._seen:
            return None  # this SYNC's input did not arrive
        self._seen = observed.counts[kind]
        x = observed.target_m if self.feed == "reference" else observed.position_m
        assert x is not None
        # over the SYNCs since the last input: a stall is no jump in speed
        v = (
            0.0
            if self._last is None
            else (x - self._last[0]) / max(t_s - self._last[1], self.period_s)
        )
        self._last = (x, t_s)
        if self.observer is None:
            return 0.0
        ahead = x + v * self.look_ahead_cycles * self.period_s
        return self.observer.step(ahead, v)


def _progress(time_s: float, figures: dict[str, Any]) -> None:
    line = (
        f"run: {time_s:.0f} s, {figures['frames_sent']} frames sent, "
        f"{figures['inputs_missing']} SYNCs without input"
    )
    print(line, file=sys.stderr, flush=True)


def follow(
    cfg: CanConfig,
    observer: FrictionObserver | None,
    feed: Literal["reference", "measured"],
    look_ahead_cycles: int,
    duration_s: float,
    stop_request: threading.Event | None = None,
) -> dict[str, Any]:
    """Follow the NC's SYNC for ``duration_s`` with ``observer`` (None: send 0 A), then stop
    cleanly; the stream's report plus the tracking error seen on the bus: per SYNC, the
    position the drive sampled against the target it had followed for a cycle (the
    NC's target of the SYNC before, as ``record`` files them), from the first reversal of
    the target on (before it the observer's elements hold a history it never saw: joining
    an axis in motion, a table's feedforward starts 0.9 um off)."""
    cfg = replace(cfg, profile="cia402", sync_master=False)
    with Rig(cfg, builtin_drive=False) as rig:
        tx = cast(Cia402Tx, rig.tx)
        tx.recorder = Recorder(tx.codec, tx.observed.unit_m, cfg.rated_current_A)
        source = Follower(tx, observer, feed, look_ahead_cycles, cfg.cycle_period_s)
        report = stream_on(rig, source, duration_s, stop_request=stop_request,
                           progress=_progress)  # fmt: skip
        recording = tx.recorder.finish()
    target = recording.column("reference_position_m")
    error = (target - recording.column("position_m"))[next(iter(reversals(target)), len(target)) :]
    errors = error[np.isfinite(error)]
    report.update(
        feed=feed,
        inputs_missing=rig.streamer.inputs_missing,
        tracking_rms_error_m=float(np.sqrt(np.mean(errors**2))) if errors.size else math.nan,
        tracking_peak_error_m=float(np.max(np.abs(errors))) if errors.size else math.nan,
    )
    return report
