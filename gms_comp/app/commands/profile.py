"""``gms-comp profile``: write a recommended identification trajectory as canonical CSV."""

from __future__ import annotations

import argparse
import io
import json
import sys
from typing import Any

import numpy as np

from gms_comp.arguments import output_file
from gms_comp.atomic import write_text
from sim.tracegen import identification_profile

# Sample rates a test stand records at (Hz): the profile lasts about 40 s, so the upper
# bound keeps the file below a few hundred megabytes.
SAMPLE_RATE_RANGE_HZ = (10.0, 100_000.0)


def _sample_rate(value: str) -> float:
    try:
        rate = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {value!r}") from None
    lo, hi = SAMPLE_RATE_RANGE_HZ
    if not lo <= rate <= hi:
        raise argparse.ArgumentTypeError(f"must be within {lo:g}-{hi:g} Hz, got {value}")
    return rate


def register(subparsers: Any) -> None:
    """Add ``profile`` to the CLI."""
    p = subparsers.add_parser(
        "profile",
        help="write an identification trajectory (step-and-stop with varied dwell, "
        "strokes at several speeds, presliding cycles) as CSV",
    )
    p.add_argument(
        "out", type=output_file, help="output CSV (time_s, reference_position_m, velocity_m_s)"
    )
    p.add_argument(
        "--sample-rate-hz",
        type=_sample_rate,
        default=1000.0,
        help=f"samples per second ({SAMPLE_RATE_RANGE_HZ[0]:g}-{SAMPLE_RATE_RANGE_HZ[1]:g} Hz)",
    )
    p.add_argument("--json", action="store_true", help="print the result as JSON on stdout")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Write the profile (atomically) and say what was written."""
    t, x, v = identification_profile(args.sample_rate_hz)
    buf = io.StringIO()
    np.savetxt(
        buf,
        np.column_stack([t, x, v]),
        delimiter=",",
        comments="",
        fmt="%.12g",
        header="time_s,reference_position_m,velocity_m_s",
    )
    write_text(args.out, buf.getvalue())
    doc = {"file": str(args.out), "samples": int(t.size), "duration_s": float(t[-1])}
    if args.json:
        sys.stdout.write(json.dumps(doc) + "\n")
        print(f"wrote {args.out}", file=sys.stderr)
    else:
        print(f"identification profile: {t.size} samples, {t[-1]:.1f} s")
        print(f"wrote {args.out}")
    return 0
