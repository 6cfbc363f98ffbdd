"""``gms-comp table``: reduce a config's ball model to a GMS bristle-element table."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from typing import Any

from gms_comp.arguments import input_file, output_file
from gms_comp.physics.config import load_ball_config
from gms_comp.tables.reduction import load_table_config, reduce_to_gms
from gms_comp.tables.table import write_table
from sim.scenarios import load_plant

# The [table] elements range of the config (gms_comp.tables.reduction.TableConfig).
MAX_ELEMENTS = 1024


def _element_count(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
    if not 1 <= value <= MAX_ELEMENTS:
        raise argparse.ArgumentTypeError(f"must be in [1, {MAX_ELEMENTS}], got {value}")
    return value


def _loads(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be comma-separated numbers, got {text!r}") from None
    if not all(v > 0 and v < float("inf") for v in values):
        raise argparse.ArgumentTypeError(f"ball loads must be finite and > 0, got {text!r}")
    return values


def register(subparsers: Any) -> None:
    """Add the ``table`` subcommand to ``subparsers``."""
    parser = subparsers.add_parser(
        "table",
        help="reduce the ball model to a GMS table",
        description=(
            "Fit N Maxwell-slip elements to the configured ball set's transient friction "
            "(bounded least squares on its virgin curve and a training path), scale them to "
            "the whole axis ([plant] ball_set_count ball sets) and write the table as JSON, "
            "with its fidelity over the seed's Fig. 7 profile and a random multi-amplitude path."
        ),
    )
    parser.add_argument(
        "config", nargs="?", type=input_file, help="config TOML (default: the seed's Table 1)"
    )
    parser.add_argument(
        "-o", "--output", type=output_file, required=True, help="table file to write (JSON)"
    )
    parser.add_argument(
        "--elements",
        type=_element_count,
        metavar="N",
        help=f"number of elements, 1..{MAX_ELEMENTS} (default: [table] elements)",
    )
    parser.add_argument(
        "--family-loads",
        type=_loads,
        metavar="N1,N2,...",
        help="also fit a load family at these ball loads in N (default: [table] family_loads_N)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout only")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Reduce the config's ball model to a GMS table and write it."""
    start = time.perf_counter()
    cfg = load_ball_config(args.config)
    table_cfg = load_table_config(cfg.path)
    if args.family_loads is not None:
        table_cfg = dataclasses.replace(table_cfg, family_loads_N=args.family_loads)
    ball_sets = load_plant(args.config).ball_set_count
    table = reduce_to_gms(
        cfg, args.elements, table_cfg, ball_sets=ball_sets, progress=sys.stderr.isatty()
    )
    write_table(args.output, table)
    family = table.load_family
    summary = {
        "table": str(args.output),
        "config": table.source_config,
        "config_sha256": table.source_sha256,
        "elements": table.n_elements,
        "slip_level": table.params.slip_level,
        "ball_sets": ball_sets,
        "sliding_force_N": table.params.slip_level * float(table.params.limit_N.sum()),
        "fidelity": {"rms_rel": table.fidelity.rms_rel, "max_rel": table.fidelity.max_rel},
        "family_loads_N": [] if family is None else family.normal_load_N.tolist(),
        "seconds": time.perf_counter() - start,
    }
    if args.json:
        print(json.dumps(summary))
        print(f"wrote {args.output}", file=sys.stderr)
    else:
        print(
            f"wrote {args.output}: {table.n_elements} elements, {ball_sets:g} ball sets "
            f"(sliding force {summary['sliding_force_N']:.4g} N), "
            f"rms {100 * table.fidelity.rms_rel:.2f} %, max {100 * table.fidelity.max_rel:.2f} % "
            f"of the sliding force ({summary['seconds']:.1f} s)"
        )
    return 0
