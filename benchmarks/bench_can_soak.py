"""CAN soak: every frame fault, sustained delays, stalls and a second compensator, many seeds.

Per seed and variant (cia402 as SYNC master, e2e, cia402 following an NC's SYNC), one
run of 0.9 s with, at once: drop, delay, duplicate, reorder and corrupt at 0.3-0.5
each, a short and a long stall and bus-off (as ``tests/test_can_combined.py``), then
two windows of a sustained delay (every frame held 1-10 cycles, drawn per seed), then a
clean tail. Each run goes twice: stepped (exact, repeatable) and on the wall clock (the
drive emulator in its own thread). Then, per seed and profile, a second compensator
started at a moment of the first one's set-up (swept over the set-up by the seed), both
with the drive emulator as a separate node of the channel.

Printed as JSON, per variant and mode:

- ``stale_or_corrupt_applied``: the stream audit's count (the target is 0);
- ``applied_during_sustained_delays``: frames applied while every frame was held
  longer than the window (target 0);
- ``max_fallback_s`` against ``fallback_limit_s``: the longest a non-zero value stayed
  applied after the last fresh frame (``rx_timeout + ramp``);
- ``max_recovery_cycles``: from the end of the last delay to a frame applied again;
- ``frames_rejected`` by reason (the faults really hit);

and for the second compensator: ``foreign_applied`` (applied frames of a compensator
while the other's session was held: the target is 0), how the pairs ended, and the
stale count of both streams.

    python benchmarks/bench_can_soak.py [--seeds 50] [--first-seed 0] [--skip-real-time]
"""

from __future__ import annotations

import argparse
import bisect
import itertools
import json
import math
import os
import random
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import can

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_can_combined import VARIANTS, fault_specs, wave

from firmware_bridge.emulator import DriveEmulator
from firmware_bridge.faults import parse_fault
from firmware_bridge.realtime import stream_on
from firmware_bridge.session import Rig
from firmware_bridge.settings import CanConfig
from firmware_bridge.streamer import ChannelTakenError

DURATION_S = 0.9
DELAYS_START_S = 0.62
DELAY_WINDOW_S = 0.08
SETUP_S = 0.3  # the first compensator's set-up (observer, tables), swept by the second


def delay_windows(seed: int) -> list[tuple[int, float, float]]:
    """Two sustained delays after the other faults: (cycles, start, end)."""
    rng = random.Random(10_000 + seed)
    first = DELAYS_START_S
    second = first + DELAY_WINDOW_S + 0.02
    return [
        (rng.randint(1, 10), first, first + DELAY_WINDOW_S),
        (rng.randint(1, 10), second, second + DELAY_WINDOW_S),
    ]


def specs(seed: int) -> list[str]:
    delays = [f"delay={n}@{a:.3f}-{b:.3f}" for n, a, b in delay_windows(seed)]
    return [*fault_specs(seed), *delays]


def config(variant: str, tag: str) -> CanConfig:
    return replace(
        CanConfig(),
        max_current_A=1.0,
        channel=f"soak-{os.getpid()}-{tag}",
        **VARIANTS[variant],
    )


def outcome(
    rig: Rig, report: dict[str, Any], seed: int, to_stream: Callable[[float], float]
) -> dict[str, Any]:
    """Fallback, recovery and applications inside the sustained delays, from the drive's
    logs, their times on the stream's clock (``to_stream``: the faults' windows are)."""
    cfg = rig.cfg
    period = cfg.cycle_period_s
    # the fallback on the drive's clock alone; the windows on the stream's
    applied_at = sorted(t for t, _ in rig.drive.applied_log)
    applied = [to_stream(t) for t in applied_at]
    outputs = rig.drive.output_log or []
    held, i = 0.0, 0
    last_fresh: float | None = None
    for t, value in outputs:
        while i < len(applied_at) and applied_at[i] <= t + 1e-9:
            last_fresh = applied_at[i]
            i += 1
        if last_fresh is not None and value != 0.0:
            held = max(held, t - last_fresh + period)
    # inside a delay longer than the window, after the frames sent before it were due
    # (with two cycles' margin for the loop's jitter around the window's edges)
    in_delays = sum(
        1
        for n, a, b in delay_windows(seed)
        if n > cfg.max_frame_age_cycles + 1
        for t in applied
        if a + (n + 2) * period <= t < b - 2 * period
    )
    end = delay_windows(seed)[-1][2]
    after = [t for t in applied if t >= end]
    return {
        "stale": report["stale_or_corrupt_applied"],
        "in_delays": in_delays,
        "fallback_s": held,
        "fallback_limit_s": cfg.fallback_time_s,
        "recovery_cycles": round((after[0] - end) / period) if after else None,
        "rejected": report["frames_rejected"],
    }


def stepped(variant: str, seed: int) -> dict[str, Any]:
    cfg = config(variant, f"st-{variant}-{seed}")
    period = cfg.cycle_period_s
    with Rig(cfg, [parse_fault(s) for s in specs(seed)], seed=seed) as rig:
        rig.drive.output_log = []
        for k in range(round(DURATION_S / period)):
            rig.step(k, wave(k))
        report = rig.report()
        return outcome(rig, report, seed, lambda t: t)


def real_time(variant: str, seed: int) -> dict[str, Any]:
    cfg = config(variant, f"rt-{variant}-{seed}")
    # each cycle's start on the wall clock and on the stream's: a late loop slips (its
    # schedule moves on), so the two part by the slips, and the faults' windows are on the
    # stream's clock
    starts: list[tuple[float, float]] = []

    def source(t_s: float) -> float:
        starts.append((time.time(), t_s))
        return wave(round(t_s * 1e3))

    def to_stream(t_wall: float) -> float:
        """A wall-clock time on the stream's clock: after the last cycle started by then."""
        i = max(0, bisect.bisect_right(starts, (t_wall, math.inf)) - 1)
        wall, stream = starts[i]
        return stream + (t_wall - wall)

    with Rig(cfg, [parse_fault(s) for s in specs(seed)], seed=seed) as rig:
        rig.drive.output_log = []
        report = stream_on(rig, source, DURATION_S)
        return outcome(rig, report, seed, to_stream)


def second_compensator(profile: str, index: int, pairs: int) -> dict[str, Any]:
    """The first compensator sets up for SETUP_S (the channel watched), then streams 0.4 s;
    the second starts ``index / (pairs - 1)`` of the way through that set-up and does the
    same. The drive is a node of its own on the channel."""
    cfg = config("e2e" if profile == "e2e" else "cia402", f"2nd-{profile}-{index}")
    start_second_s = SETUP_S * index / max(1, pairs - 1)
    sent: dict[str, list[tuple[float, float, bytes]]] = {}
    why: dict[str, str] = {}
    stop = threading.Event()
    with can.Bus(interface="virtual", channel=cfg.channel) as drive_bus:
        drive = DriveEmulator(cfg, drive_bus)
        drive_thread = threading.Thread(target=drive.run, args=(stop, time.time), daemon=True)
        drive_thread.start()

        def compensator(name: str, delay_s: float) -> None:
            time.sleep(delay_s)
            try:
                with Rig(cfg, builtin_drive=False) as rig:
                    sent[name] = rig.streamer.sent_log  # filled as it streams
                    with rig.watching():
                        time.sleep(SETUP_S)
                    stream_on(rig, lambda t_s: 0.3 + 0.1 * (name == "b"), 0.4)
            except ChannelTakenError as err:
                why[name] = str(err)

        threads = [
            threading.Thread(target=compensator, args=("a", 0.0)),
            threading.Thread(target=compensator, args=("b", start_second_s)),
        ]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        stop.set()
        drive_thread.join()
    payloads = {name: {d for _, _, d in log} for name, log in sent.items()}
    owners = [
        next((n for n, own in payloads.items() if data in own), None)
        for _, data in drive.applied_log
    ]
    # one compensator's commands applied after the other's, or no one's: foreign
    switches = sum(1 for a, b in itertools.pairwise(owners) if a != b)
    return {
        "start_second_s": round(start_second_s, 4),
        "applied_from": sorted({o for o in owners if o is not None}),
        "foreign_applied": switches + owners.count(None),
        "refused": {name: text[:70] for name, text in sorted(why.items())},
        "foreign_refused_by_drive": drive.status()["frames_rejected"]["foreign"],
    }


def summarise(runs: list[dict[str, Any]]) -> dict[str, Any]:
    recoveries = [r["recovery_cycles"] for r in runs]
    rejected: Counter[str] = Counter()
    for r in runs:
        rejected.update(r["rejected"])
    return {
        "runs": len(runs),
        "stale_or_corrupt_applied": sum(r["stale"] for r in runs),
        "runs_with_stale": sum(r["stale"] > 0 for r in runs),
        "applied_during_sustained_delays": sum(r["in_delays"] for r in runs),
        "max_fallback_s": round(max(r["fallback_s"] for r in runs), 6),
        "fallback_limit_s": runs[0]["fallback_limit_s"],
        "max_recovery_cycles": None if None in recoveries else max(recoveries),
        "runs_without_recovery": recoveries.count(None),
        "frames_rejected": dict(rejected),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seeds", type=int, default=50, help="seeds per variant (50)")
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--skip-real-time", action="store_true")
    args = parser.parse_args()
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    out: dict[str, Any] = {"seeds": [seeds.start, seeds.stop - 1]}
    started = time.monotonic()
    for variant in VARIANTS:
        modes: dict[str, Any] = {"stepped": stepped}
        if not args.skip_real_time:
            modes["real_time"] = real_time
        for mode, run in modes.items():
            runs = [run(variant, seed) for seed in seeds]
            out[f"{variant}/{mode}"] = summarise(runs)
            print(f"{variant}/{mode}: {out[f'{variant}/{mode}']}", file=sys.stderr)
    if not args.skip_real_time:
        for profile in ("cia402", "e2e"):
            pairs = [second_compensator(profile, i, len(seeds)) for i in range(len(seeds))]
            out[f"second_compensator/{profile}"] = {
                "pairs": len(pairs),
                "foreign_applied": sum(p["foreign_applied"] for p in pairs),
                "applied_from": dict(Counter("+".join(p["applied_from"]) or "none" for p in pairs)),
                "both_refused": sum(len(p["refused"]) == 2 for p in pairs),
                "examples": pairs[:: max(1, len(pairs) // 5)],
            }
            print(f"second/{profile}: {out[f'second_compensator/{profile}']}", file=sys.stderr)
    out["load_1min"] = os.getloadavg()[0]
    out["elapsed_s"] = round(time.monotonic() - started, 1)
    print(json.dumps(out, default=str))


if __name__ == "__main__":
    main()
