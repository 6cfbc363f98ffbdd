"""``gms-comp profile``: write a recommended identification trajectory as canonical CSV."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from sim.tracegen import identification_profile

from ..errors import TraceError


def register(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "profile",
        help="write an identification trajectory (step-and-stop with varied dwell, "
        "strokes at several speeds, presliding cycles) as CSV",
    )
    p.add_argument("out", help="output CSV (time_s, reference_position_m, velocity_m_s)")
    p.add_argument("--sample-rate-hz", type=float, default=1000.0)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if not args.sample_rate_hz > 0:
        raise TraceError(f"--sample-rate-hz must be > 0, got {args.sample_rate_hz}")
    t, x, v = identification_profile(args.sample_rate_hz)
    np.savetxt(
        args.out,
        np.column_stack([t, x, v]),
        delimiter=",",
        comments="",
        fmt="%.12g",
        header="time_s,reference_position_m,velocity_m_s",
    )
    return 0
