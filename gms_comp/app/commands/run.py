"""``gms-comp run``: the compensator in production, following the machine on the CAN bus.

It answers each SYNC of the NC with the torque offset (0x60B2) for the next: the GMS
feedforward of ``--table`` (a physics table or a diagnosed, extended one; its force is
the whole axis's friction) along the target position the NC sends the drive
(``--feed reference``) or the drive's position actual (``--feed measured``), with the
``[compensator]`` look-ahead, limits and rate limit. Every rule of the CAN transport
holds (the drive's session, frames dated by the drive's cycle, the ramp); Ctrl-C and
SIGTERM stop it in order (ramp to 0 A, the session released; the NC keeps the drive),
exit 130/143. Progress goes to stderr; the report to stdout (``--json``) or ``-o``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from gms_comp.app.live.arguments import add_bus_arguments, bus_config, checked_duration
from gms_comp.app.live.follow import follow
from gms_comp.app.signals import stop_requests
from gms_comp.arguments import input_file, output_file
from gms_comp.atomic import write_text
from gms_comp.runtime.observer import FrictionObserver, check_table_fits
from gms_comp.tables.table import read_table
from sim.scenarios import load_scenario

MAX_DURATION_S = 24 * 3600.0
NO_TABLE = "none"


def register(subparsers: Any) -> None:
    """Add ``run`` to the CLI."""
    p = subparsers.add_parser(
        "run",
        help="follow the NC on the CAN bus and send the GMS feedforward (production mode)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_bus_arguments(p)
    p.add_argument(
        "--table",
        required=True,
        metavar="TABLE",
        help="GMS table (gms-comp table, or diagnose --table); 'none' sends 0 A",
    )
    p.add_argument("--feed", choices=("reference", "measured"), help="override [compensator] feed")
    p.add_argument("--duration", type=float, default=MAX_DURATION_S, metavar="S",
                   help="stop after S seconds (default: until Ctrl-C or SIGTERM)")  # fmt: skip
    p.add_argument("--json", action="store_true", help="print the report as JSON on stdout")
    p.add_argument("-o", "--output", type=output_file, metavar="FILE.json", help="write the report")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Follow the bus until the duration ends or a signal stops it; report."""
    checked_duration(args.duration, MAX_DURATION_S)
    path, cfg = bus_config(args)
    s = load_scenario(path)
    observer = None
    if args.table != NO_TABLE:
        table = read_table(input_file(args.table))
        comp = s.compensator
        check_table_fits(table, args.table, s.plant.force_constant_N_per_A,
                         comp.friction_level_scale, comp.current_limit_A)  # fmt: skip
        observer = FrictionObserver(
            table, s.plant.force_constant_N_per_A, cfg.cycle_period_s,
            comp.friction_level_scale, comp,
        )  # fmt: skip
    feed = args.feed or s.compensator.feed
    print(f"following the NC on {cfg.interface} {cfg.channel!r} (feed {feed}, table "
          f"{args.table}): Ctrl-C stops", file=sys.stderr, flush=True)  # fmt: skip
    with stop_requests() as stop, stop.deferred() as stopping:
        report = follow(cfg, observer, feed, s.compensator.look_ahead_cycles, args.duration,
                        stopping)  # fmt: skip
    report["table"] = args.table
    text = json.dumps(report, indent=2, sort_keys=True)
    if args.json:
        print(text)
    else:
        print(summary(report, cfg.cycle_period_s))
    if args.output is not None:
        written = write_text(Path(args.output), text + "\n")
        print(f"wrote {written}", file=sys.stderr if args.json else sys.stdout)
    if report.get("interrupted"):
        print(f"gms-comp run: stopped by {stop.name or 'Ctrl-C'}: ramped to 0 A, session "
              "released", file=sys.stderr)  # fmt: skip
        return stop.exit_code
    return 0


def summary(report: dict[str, Any], period_s: float) -> str:
    """A few lines: frames, the reaction to SYNC, the tracking error, how it ended."""
    lines = [
        f"answered {report.get('cycles', 0)} SYNCs ({report['frames_sent']} frames, "
        f"{report['inputs_missing']} without input, table {report['table']}, feed "
        f"{report['feed']})",
    ]
    if "sync_to_sent_p99_s" in report:
        lines.append(
            f"SYNC to frame sent: p50 {report['sync_to_sent_p50_s'] * 1e6:.0f} us, p99 "
            f"{report['sync_to_sent_p99_s'] * 1e6:.0f} us; within the {period_s * 1e3:g} ms "
            f"cycle: {100 * report['answered_within_cycle']:.2f} %"
        )
    lines.append(
        f"tracking error (target - position actual): RMS "
        f"{report['tracking_rms_error_m'] * 1e6:.3f} um, peak "
        f"{report['tracking_peak_error_m'] * 1e6:.3f} um"
    )
    if report.get("sync_lost"):
        lines.append("the NC's SYNC stopped: the stream ended silent")
    elif "end_of_stream" in report:
        lines.append(f"end: {report['end_of_stream']}")
    return "\n".join(lines)
