"""Stale frames applied in real time under CPU load: the combined-fault stream, many seeds.

Runs the combined-fault stream of ``tests/test_can_combined.py`` (every frame fault
at 0.3-0.5, a short and a long stall, bus-off) on the wall clock, the drive
emulator in its own thread (as ``test_combined_faults_in_real_time`` does), for
``--seeds`` seeds per variant (cia402 as SYNC master, e2e, cia402 following an
NC's SYNC), optionally with ``--busy K`` busy-loop processes beside it, and
prints per variant as JSON:

- ``stale_or_corrupt_applied``: the stream audit's count (the target is 0);
- ``frames_rejected``: frames the drive refused (the faults really hit);
- ``max_applied_age_cycles``: the oldest frame applied, by the audit's clock (its
  age in cycles from the end of its send, less the transport), against the
  window ``max_frame_age_cycles``: how close the drive came to the boundary;
- ``max_fallback_s`` against ``fallback_limit_s``: the longest time a non-zero
  value stayed applied after the last fresh frame (``rx_timeout + ramp``);
- ``max_recovery_cycles``: from the end of the faults to the first frame applied
  (null if a run applied none after them: under heavy load a late loop's frames
  are stale, and cia402 drops RPDOs whose SYNC came more than 1.5 cycles late);
- ``flagged``: for each frame the audit flagged, its seed, its age past the
  window in cycles, and its history in cycles after the end of its send (its
  receptions, its application, the frames the drive got meanwhile: ``080`` SYNC
  with its counter byte, ``201`` RPDO1 or ``120`` FfCommand with the payload).

Stepped runs of the same faults are exact and in ``tests/test_can_combined.py``.

    python benchmarks/bench_can_rt_stale.py [--seeds 20] [--busy 2] [--variant cia402 ...]
"""

from __future__ import annotations

import argparse
import bisect
import json
import os
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import can

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_can_combined import FAULTS_END_S, VARIANTS, fault_specs, wave

from firmware_bridge.faults import parse_fault
from firmware_bridge.freshness import is_fresh
from firmware_bridge.session import Rig, stream_on
from firmware_bridge.settings import CanConfig

DURATION_S = 0.8


def run_one(variant: str, seed: int) -> dict[str, Any]:
    """One real-time combined-fault run; its audit count and fallback/recovery figures."""
    cfg = replace(
        CanConfig(),
        max_current_A=1.0,
        channel=f"bench-rt-stale-{os.getpid()}-{variant}-{seed}",
        **VARIANTS[variant],  # type: ignore[arg-type]
    )
    faults_end_wall: list[float] = []

    def source(t_s: float) -> float:
        if t_s >= FAULTS_END_S and not faults_end_wall:
            faults_end_wall.append(time.time())
        return wave(round(t_s * 1e3))

    faults = [parse_fault(s) for s in fault_specs(seed)]
    received: list[tuple[float, int, bytes]] = []  # what the drive got: stamp, id, payload
    with Rig(cfg, faults, seed=seed) as rig:
        rig.drive.output_log = []
        drive_handle = rig.drive.handle

        def handle(msg: can.Message, now_s: float) -> None:
            received.append((now_s, msg.arbitration_id, bytes(msg.data)))
            drive_handle(msg, now_s)

        rig.drive.handle = handle  # type: ignore[method-assign]
        report = stream_on(rig, source, DURATION_S)
        period = cfg.cycle_period_s
        applied = rig.drive.applied_log
        outputs = rig.drive.output_log
        sent = rig.streamer.sent_log
    transport = report["transport_cycles"]
    fresh_times = [t for t, _ in applied]
    held = 0.0
    for t, value in outputs:
        i = bisect.bisect_right(fresh_times, t + 1e-9)
        if i and value != 0.0:
            held = max(held, t - fresh_times[i - 1])
    end = faults_end_wall[0] if faults_end_wall else float("inf")
    first_after = next((t for t in fresh_times if t >= end), None)
    recovery = None if first_after is None else round((first_after - end) / period)
    flagged = []
    oldest = -float("inf")
    by_payload: dict[bytes, list[tuple[float, float]]] = {}
    for before, after, data in sent:
        by_payload.setdefault(data, []).append((before, after))
    for t, data in applied:
        # the audit's match: the latest send of this payload begun by the application
        sends = [b for b in by_payload.get(data, []) if b[0] <= t + 1e-6 * period]
        bounds = sends[-1] if sends else None
        if bounds is None:
            flagged.append({"seed": seed, "unsent": True})
            continue
        age = (t - bounds[1]) / period - transport
        oldest = max(oldest, age)
        if not is_fresh(age, cfg.max_frame_age_cycles):
            flagged.append(
                {
                    "seed": seed,
                    "past_window_cycles": age - cfg.max_frame_age_cycles,
                    **_trace(t, data, bounds, received, period),
                }
            )
    return {
        "stale": report["stale_or_corrupt_applied"],
        "rejected": sum(report["frames_rejected"].values()),
        "resync": report["sessions_granted"],
        "fallback_s": held + period,
        "fallback_limit_s": cfg.fallback_time_s,
        "recovery_cycles": recovery,
        "late_cycles": report["late_cycles"],
        "max_applied_age": oldest,
        "window": cfg.max_frame_age_cycles,
        "flagged": flagged,
    }


def _trace(
    applied_s: float,
    data: bytes,
    sent: tuple[float, float],
    received: list[tuple[float, int, bytes]],
    period_s: float,
) -> dict[str, Any]:
    """A flagged frame's history in cycles after the end of its send: receptions, the
    frames the drive got around it, its application."""

    def cycles(t: float) -> float:
        return round((t - sent[1]) / period_s, 3)

    near = [
        f"{cycles(t)}:{arb:03X}:{payload.hex()}"
        for t, arb, payload in received
        if sent[0] - 2 * period_s <= t <= applied_s + period_s
    ]
    return {
        "payload": data.hex(),
        "send_s": sent,
        "received_at_cycles": [cycles(t) for t, _, payload in received if payload == data],
        "applied_at_cycles": cycles(applied_s),
        "drive_got": near,
    }


def main() -> None:
    """Run the variants and print the JSON summary (progress per run on stderr)."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seeds", type=int, default=20, help="seeds per variant (20)")
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--busy", type=int, default=0, help="busy-loop processes beside (0)")
    parser.add_argument("--variant", action="append", choices=list(VARIANTS))
    args = parser.parse_args()
    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.busy)]
    results: dict[str, Any] = {}
    try:
        for variant in args.variant or list(VARIANTS):
            seeds = range(args.first_seed, args.first_seed + args.seeds)
            runs = []
            for seed in seeds:
                runs.append(run_one(variant, seed))
                r = runs[-1]
                print(f"{variant} seed {seed}: {r}", file=sys.stderr)
            recoveries = [r["recovery_cycles"] for r in runs]
            results[variant] = {
                "runs": len(runs),
                "stale_or_corrupt_applied": sum(r["stale"] for r in runs),
                "runs_with_stale": sum(r["stale"] > 0 for r in runs),
                "frames_rejected": sum(r["rejected"] for r in runs),
                "frames_resync": sum(r["resync"] for r in runs),
                "max_fallback_s": max(r["fallback_s"] for r in runs),
                "fallback_limit_s": runs[0]["fallback_limit_s"],
                "fallback_ok": all(r["fallback_s"] <= r["fallback_limit_s"] + 1e-9 for r in runs),
                "max_recovery_cycles": None if None in recoveries else max(recoveries),
                "late_cycles": sum(r["late_cycles"] for r in runs),
                "max_applied_age_cycles": round(max(r["max_applied_age"] for r in runs), 4),
                "max_frame_age_cycles": runs[0]["window"],
                "flagged": [f for r in runs for f in r["flagged"]],
            }
    finally:
        for proc in busy:
            proc.kill()
            proc.wait()
    print(json.dumps({"busy_loops": args.busy, "load_1min": os.getloadavg()[0], **results}))


if __name__ == "__main__":
    main()
