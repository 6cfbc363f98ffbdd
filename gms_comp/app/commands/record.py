"""``gms-comp record``: record the axis on the CAN bus into a trace ``diagnose`` reads.

One row per SYNC: position actual (0x6064), velocity actual (0x606C), current actual
(0x6078) from the drive's TPDOs, the NC's target position (0x607A) as it passes, and the
friction force from the current (``k_f * current - m * target acceleration``, with
``[plant]``'s force constant and moving mass). A lost or late PDO leaves its row's
fields empty (NaN) and is counted in the JSON sidecar ``OUT.csv.json`` (drive, scaling,
PDO mapping, samples lost), never interpolated.

With an NC on the bus it listens for ``--duration``; without one it drives the axis
itself along the identification profile of ``gms-comp profile`` (NMT start, the CiA 402
enable sequence, cyclic synchronous position as SYNC master) and disables it at the end.
``--fault drop:0.05`` (or ``delay=3:0.1``) loses or delays the drive's TPDOs on the way
in, to see what a lossy link records.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from firmware_bridge.faults import parse_fault
from gms_comp.app.live.arguments import add_bus_arguments, bus_config, checked_duration
from gms_comp.app.live.recording import (
    drive_and_record,
    listen_and_record,
    nc_on_bus,
    profile_targets,
    to_trace,
    write_recording,
)
from gms_comp.app.signals import stop_requests
from gms_comp.arguments import output_file
from sim.scenarios import load_scenario

MAX_LISTEN_S = 3600.0


def register(subparsers: Any) -> None:
    """Add ``record`` to the CLI."""
    p = subparsers.add_parser(
        "record",
        help="record the axis on the CAN bus (position, current, target per SYNC) as a trace",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("out", type=output_file, metavar="OUT.csv", help="trace CSV to write")
    add_bus_arguments(p)
    p.add_argument(
        "--duration",
        type=float,
        default=30.0,
        metavar="S",
        help="with an NC on the bus: seconds to record (30)",
    )
    p.add_argument(
        "--scale",
        type=float,
        default=1.0,
        choices=(0.25, 0.5, 1.0),
        help="without an NC: length of the identification profile (1.0: about 40 s)",
    )
    p.add_argument("--fault", action="append", default=[], metavar="SPEC",
                   help="drop or delay the drive's TPDOs on the way in (repeatable)")  # fmt: skip
    p.add_argument("--seed", type=int, default=0, help="seed of the faults")
    p.add_argument("--json", action="store_true", help="print the sidecar as JSON on stdout")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Record, write the trace and its sidecar, say what was lost."""
    checked_duration(args.duration, MAX_LISTEN_S)
    path, cfg = bus_config(args)
    plant = load_scenario(path).plant
    faults = [parse_fault(spec) for spec in args.fault]
    note = print if not args.json else lambda *a, **k: print(*a, **k, file=sys.stderr)
    with stop_requests() as stop:
        if nc_on_bus(cfg):
            note(f"an NC drives the bus: recording {args.duration:g} s", flush=True)
            recording = listen_and_record(cfg, args.duration, faults, args.seed)
            source = "record: NC on the bus"
        else:
            note("no NC on the bus: driving the axis along the identification profile",
                 flush=True)  # fmt: skip
            targets = profile_targets(cfg.cycle_period_s, args.scale).tolist()
            with stop.deferred() as stopping:
                recording, _ = drive_and_record(cfg, targets, faults, args.seed, stopping)
            source = f"record: identification profile (scale {args.scale:g})"
    recorded = to_trace(recording, cfg, plant, source)
    written = write_recording(recorded, Path(args.out))
    side = recorded.sidecar
    if args.json:
        print(json.dumps(side, indent=2))
    else:
        print(
            f"recorded {side['samples']} samples ({side['samples'] * cfg.cycle_period_s:.1f} s), "
            f"{side['samples_missing']} missing (lost: {side['lost']}, late: {side['late']})"
        )
    for p in written:
        print(f"wrote {p}", file=sys.stderr if args.json else sys.stdout)
    return stop.exit_code if stop.signum is not None else 0
