"""Loop time of the feedforward stream at 1 kHz: observer + encode + send, per profile.

Runs ``gms-comp stream``'s real-time loop (GMS observer along the config's sine,
drive emulator in its own thread on the virtual bus) and prints JSON with the
p99 loop time, deadline statistics and bus load. Target: p99 <= 200 us.

    python benchmarks/bench_stream.py [--duration 3] [--config FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
from dataclasses import replace
from pathlib import Path

from firmware_bridge.realtime import run_stream
from firmware_bridge.settings import load_can_config
from gms_comp.app.commands.stream import gms_observer_source
from gms_comp.config import default_config_path

TARGET_P99_S = 200e-6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--duration", type=float, default=3.0)
    parser.add_argument("--config", type=Path, default=default_config_path())
    args = parser.parse_args()
    results = {}
    for profile in ("cia402", "e2e"):
        cfg = replace(
            load_can_config(args.config),
            profile=profile,
            cycle_period_s=1e-3,
            channel=f"bench-{profile}",
        )
        source = gms_observer_source(args.config, cfg, args.duration)
        report = run_stream(cfg, source, args.duration)
        results[profile] = {
            "source": "gms_observer",
            "loop_time_p99_s": report["loop_time_p99_s"],
            "loop_time_max_s": report["loop_time_max_s"],
            "meets_p99_target": report["loop_time_p99_s"] <= TARGET_P99_S,
            "late_cycles": report["late_cycles"],
            "cycles": report["cycles"],
            "max_lateness_s": report["max_lateness_s"],
            "bus_load": report["bus_load"],
            "frames_sent": report["frames_sent"],
            "frames_applied": report["frames_applied"],
            "stale_or_corrupt_applied": report["stale_or_corrupt_applied"],
        }
    print(
        json.dumps(
            {
                "benchmark": "stream_1kHz",
                "duration_s": args.duration,
                "target_p99_s": TARGET_P99_S,
                "machine": {
                    "cpus": os.cpu_count(),
                    "python": platform.python_version(),
                    "load_average_1min": os.getloadavg()[0],
                },
                "profiles": results,
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
