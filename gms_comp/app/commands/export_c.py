"""``gms-comp export-c``: the observer of a table as C99 source for a drive."""

from __future__ import annotations

import argparse
import json
import math
import sys
import zlib
from typing import Any

from gms_comp.arguments import input_file, output_dir
from gms_comp.runtime.export_c import export_c
from gms_comp.runtime.observer import check_table_fits
from gms_comp.tables.table import read_table
from sim.scenarios import load_scenario

#: The current-loop rate the observer is generated for by default, Hz.
DEFAULT_RATE_HZ = 16000.0


def _rate(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number, got {text!r}") from None
    if not (math.isfinite(value) and 100.0 <= value <= 1e6):
        raise argparse.ArgumentTypeError(f"must be in [100, 1e6] Hz, got {text!r}")
    return value


def register(subparsers: Any) -> None:
    """Add the ``export-c`` subcommand to ``subparsers``."""
    p = subparsers.add_parser(
        "export-c",
        help="generate the GMS observer of a table as C99 source for a drive",
        description=(
            "Write gms_observer.h, gms_observer.c (C99, float32, no heap, no libm call) and "
            "gms_table.bin (the table object with its CRC-32, for a download) into DIR: the "
            "table's GMS and the extensions a drive can run, with [compensator]'s limits, "
            "rate limit and adaptation and [plant]'s force constant from CONFIG. Build: "
            "cc -std=c99 -O2 -c DIR/gms_observer.c (docs/in-drive.md)."
        ),
    )
    p.add_argument("table", type=input_file, metavar="TABLE", help="GMS table (JSON)")
    p.add_argument("-o", "--output", type=output_dir, required=True, metavar="DIR")
    p.add_argument(
        "--config", type=input_file, help="config TOML ([compensator], [plant]; default Table 1)"
    )
    p.add_argument(
        "--rate-hz",
        type=_rate,
        default=DEFAULT_RATE_HZ,
        metavar="HZ",
        help=f"the rate gms_step runs at in the drive (default {DEFAULT_RATE_HZ:g})",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout only")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Generate the C observer of the table and say what it holds."""
    s = load_scenario(args.config)
    comp, kf = s.compensator, s.plant.force_constant_N_per_A
    table = read_table(args.table)
    check_table_fits(table, str(args.table), kf, comp.friction_level_scale, comp.current_limit_A)
    args.output.mkdir(parents=True, exist_ok=True)
    files, obj = export_c(table, args.output, comp, kf, args.rate_hz, str(args.table))
    blob = obj.to_bytes()
    summary = {
        "table": str(args.table),
        "files": [str(f) for f in files],
        "elements": obj.counts["n_elements"],
        "level_points": obj.counts["level_points"],
        "stribeck_points": obj.counts["stribeck_points"],
        "ripples": obj.counts["ripples"],
        "extensions": [e.effect for e in table.extensions],
        "rate_Hz": args.rate_hz,
        "table_object_bytes": len(blob),
        "table_crc32": zlib.crc32(blob[:-4]),
    }
    if args.json:
        sys.stdout.write(json.dumps(summary, indent=2) + "\n")
        return 0
    print(
        f"wrote {args.output}: {summary['elements']} elements, level table "
        f"{summary['level_points']} points, Stribeck {summary['stribeck_points']}, "
        f"{summary['ripples']} ripple(s), for {args.rate_hz:g} Hz; table object "
        f"{len(blob)} bytes, CRC-32 0x{summary['table_crc32']:08x}"
    )
    print(f"build: cc -std=c99 -O2 -c {args.output / 'gms_observer.c'}")
    return 0
