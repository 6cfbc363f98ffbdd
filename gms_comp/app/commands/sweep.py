"""``gms-comp sweep``: one GMS table per point of a grid over config keys, on Dask."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from gms_comp.app.scaleout import add_cluster_arguments, cli_client
from gms_comp.app.sweep import load_sweep, run_sweep
from gms_comp.arguments import input_file, output_dir


def register(subparsers: Any) -> None:
    """Add the ``sweep`` subcommand to ``subparsers``."""
    parser = subparsers.add_parser(
        "sweep",
        help="generate a family of tables over a parameter grid (Dask)",
        description=(
            "Generate one GMS table per point of the grid in SWEEP.toml, on a local Dask "
            "cluster (listening on 127.0.0.1 only) or on an existing one (--scheduler, tls:// "
            "with certificates: a scheduler runs any code sent to it; never from the sweep "
            "file). A rerun into the same folder resumes: points whose whole config is "
            "unchanged are not computed again."
        ),
    )
    parser.add_argument(
        "sweep_file", type=input_file, metavar="SWEEP.toml", help="sweep definition"
    )
    add_cluster_arguments(parser)
    parser.add_argument(
        "-o",
        "--output",
        type=output_dir,
        default=Path("family"),
        help="output folder (default: family)",
    )
    parser.add_argument("--json", action="store_true", help="print the manifest as JSON")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the sweep (Dask or serial) and report its manifest."""
    spec = load_sweep(args.sweep_file)
    if args.serial:
        manifest = run_sweep(spec, args.output)
    else:
        with cli_client(args) as client:
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
    resumed = sum(1 for p in points if p.get("resumed"))
    changed = sum(1 for p in points if "note" in p)
    if resumed or changed:
        print(
            f"{resumed} resumed (their whole config unchanged), "
            f"{changed} recomputed (config changed since their table was made)"
        )
    if ok:
        worst = max(ok, key=lambda p: p["fidelity"]["rms_rel"])
        print(f"worst fidelity: rms_rel {worst['fidelity']['rms_rel']:.2%} at {worst['values']}")
    for p in points:
        if p["status"] != "ok":
            print(f"point {p['index']} {p['values']}: {p['status']}: {p.get('reason', '')}")
