"""``gms-comp sweep``: one GMS table per point of a grid over config keys, on Dask."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from ..scaleout import dask_client
from ..sweep import load_sweep, run_sweep


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "sweep",
        help="generate a family of tables over a parameter grid (Dask)",
        description=(
            "Generate one GMS table per point of the grid in SWEEP.toml, on a local Dask "
            "cluster or on an existing one (--scheduler). A rerun into the same folder "
            "resumes: points already done are not computed again."
        ),
    )
    parser.add_argument("sweep_file", type=Path, metavar="SWEEP.toml", help="sweep definition")
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="Dask scheduler address, e.g. tcp://host:8786 (default: a local cluster)",
    )
    parser.add_argument(
        "--workers", type=int, default=None, help="local cluster size (default: one per core)"
    )
    parser.add_argument("--serial", action="store_true", help="run in this process, no Dask")
    parser.add_argument(
        "-o", "--output", type=Path, default=Path("family"), help="output folder (default: family)"
    )
    parser.add_argument("--json", action="store_true", help="print the manifest as JSON")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    spec = load_sweep(args.sweep_file)
    if args.serial:
        manifest = run_sweep(spec, args.output)
    else:
        with dask_client(args.scheduler, args.workers) as client:
            manifest = run_sweep(spec, args.output, client=client)
    points = manifest["points"]
    if args.json:
        json.dump(manifest, sys.stdout, indent=2)
        print()
    else:
        _print_summary(points, args.output)
    return 0 if all(p["status"] == "ok" for p in points) else 1


def _print_summary(points: list[dict[str, Any]], out: Path) -> None:
    ok = [p for p in points if p["status"] == "ok"]
    print(f"{len(ok)}/{len(points)} tables in {out} (manifest: {out / 'manifest.json'})")
    if ok:
        worst = max(ok, key=lambda p: p["fidelity"]["rms_rel"])
        print(f"worst fidelity: rms_rel {worst['fidelity']['rms_rel']:.2%} at {worst['values']}")
    for p in points:
        if p["status"] != "ok":
            print(f"point {p['index']} {p['values']}: {p['status']}: {p.get('reason', '')}")
