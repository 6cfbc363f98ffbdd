"""``gms-comp diagnose``: where the model is wrong on a measured trace, the cause, the gain."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..config import config_hash, load_ball_config, read_toml
from ..diagnosis import emps
from ..diagnosis.run import Diagnosis, diagnose, load_diagnosis_config
from ..effects import effect_to_dict
from ..errors import GmsCompError
from ..fleet import FleetJob, diagnose_fleet, format_table
from ..gms import GmsParams
from ..reduction import reduce_to_gms
from ..scaleout import dask_client
from ..table import Extension, Fidelity, GmsTable, read_table, write_table
from ..traces import Trace, load_trace, parse_mapping


def register(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "diagnose",
        help="diagnose measured traces against the model",
        description=(
            "Diagnose one trace, or a fleet of traces in parallel on Dask (a local cluster, "
            "or an existing one with --scheduler): the named effect, its parameters and "
            "the gain per trace, and the effects that recur across the fleet."
        ),
    )
    p.add_argument(
        "traces",
        nargs="+",
        metavar="TRACE",
        help="canonical CSV, EMPS .mat, or any .csv/.mat with --map",
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="Dask scheduler for many traces, e.g. tcp://host:8786 (default: local cluster)",
    )
    p.add_argument("--workers", type=int, help="local cluster size (default: one per core)")
    p.add_argument("--serial", action="store_true", help="many traces in this process, no Dask")
    p.add_argument(
        "--config",
        help=(
            "config file: [diagnosis] section; with [bearing] and [stand] sections its ball "
            "model is reduced to a GMS table, calibrated as the baseline"
        ),
    )
    p.add_argument(
        "--table-in",
        metavar="TABLE",
        help="GMS table to calibrate as the baseline (its level, presliding, velocity level)",
    )
    p.add_argument(
        "--force-kind",
        choices=("friction", "drive"),
        help="what force_N is (default: drive for EMPS files, else friction)",
    )
    p.add_argument("--validate", metavar="TRACE2", help="held-out trace (else blocks of TRACE)")
    p.add_argument(
        "--map",
        action="append",
        default=[],
        metavar="COLUMN=EXPR",
        help="column mapping, e.g. position_m=pos_mm*0.001 (repeatable)",
    )
    p.add_argument("--json", metavar="OUT.json", help="write the result here (else stdout)")
    p.add_argument("--report", metavar="DIR", help="write plots and the extended table here")
    p.add_argument("--table", metavar="OUT", help="write the extended model as a GMS table")
    p.add_argument(
        "--closed-loop",
        nargs="?",
        const="",
        metavar="SCENARIO",
        help=(
            "simulate the axis with the diagnosed friction and compare the compensator with "
            "the baseline and the extended model (scenario config; default: Table 1's)"
        ),
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    mapping = parse_mapping(args.map, "--map") if args.map else None
    if len(args.traces) > 1 or args.scheduler:
        return _run_fleet(args, mapping)
    args.trace = args.traces[0]
    trace = load_trace(args.trace, mapping)
    validation = load_trace(args.validate, mapping) if args.validate else None
    kind = args.force_kind or trace.force_kind or "friction"
    config = load_diagnosis_config(args.config)
    result = diagnose(trace, kind, validation, config, _baseline_table(args))
    doc = result.to_json()
    doc["trace"] = str(args.trace)
    if trace.force_kind == "drive" and kind == "drive":
        doc.update(_benchmark_errors(trace, validation, result))
    if args.closed_loop is not None:
        from .diagnose_closed_loop import closed_loop_gain  # the simulated axis when asked

        doc["closed_loop"] = closed_loop_gain(result, args.closed_loop or None)
    table_path = args.table or (Path(args.report) / "extended.table.json" if args.report else None)
    if args.report:
        Path(args.report).mkdir(parents=True, exist_ok=True)
    if table_path is not None:
        write_table(table_path, _table(result, args.trace))
        doc["table"] = str(table_path)
    if args.report:
        from ..diagnosis.report import write_report  # matplotlib only when asked for

        doc["report"] = [str(p) for p in write_report(result, args.report)]
    text = json.dumps(doc, indent=2)
    if args.json:
        Path(args.json).write_text(text + "\n")
    else:
        sys.stdout.write(text + "\n")
    return 0


def _baseline_table(args: argparse.Namespace) -> GmsParams | None:
    """The GMS table to calibrate: ``--table-in``, else the ball model of a ``--config``
    that describes a bearing, else none (the free NNLS GMS)."""
    if args.table_in:
        return read_table(args.table_in).params
    if args.config and "bearing" in read_toml(args.config):
        return reduce_to_gms(load_ball_config(args.config)).params
    return None


def _run_fleet(args: argparse.Namespace, mapping: Mapping[str, str] | None) -> int:
    """Many traces: one job each, a summary row each, recurring effects across them.

    A baseline table (``--table-in`` or a bearing ``--config``) is made once here and
    calibrated on each trace by its job."""
    for flag in ("validate", "table", "closed_loop"):
        if getattr(args, flag) is not None:
            raise GmsCompError(
                f"--{flag.replace('_', '-')} applies to a single trace, not to a fleet"
            )
    table = _baseline_table(args)
    jobs = [
        FleetJob(
            trace=str(path),
            force_kind=args.force_kind,
            config=args.config,
            mapping=tuple(sorted(mapping.items())) if mapping else (),
            report_dir=args.report,
            table=table,
        )
        for path in args.traces
    ]
    if args.serial:
        summary = diagnose_fleet(jobs)
    else:
        with dask_client(args.scheduler, args.workers) as client:
            summary = diagnose_fleet(jobs, client=client)
    if args.json:
        Path(args.json).write_text(json.dumps(summary, indent=2) + "\n")
    print(format_table(summary))
    return 0 if all(row["status"] == "ok" for row in summary["traces"]) else 1


def _table(result: Diagnosis, trace_path: str) -> GmsTable:
    level = max(float(result.baseline["sliding_force_N"]), 1e-12)
    s = result.series
    worst = float(np.max(np.abs(s["force_N"] - s["extended_N"])))
    return GmsTable(
        params=result.gms,
        source_config=str(trace_path),
        source_sha256=config_hash(trace_path),
        fidelity=Fidelity(rms_rel=result.extended_rms_N / level, max_rel=worst / level),
        extensions=tuple(
            Extension(d["effect"], d["parameters"]) for d in map(effect_to_dict, result.extensions)
        ),
    )


def _benchmark_errors(trace: Trace, validation: Trace | None, result: Diagnosis) -> dict[str, Any]:
    """The EMPS benchmark's relative errors (decimated, first samples dropped) of the
    IDIM-LS reference and of our baseline and extended models."""
    s = result.series
    cut = emps.DROPPED_SAMPLES
    ref = emps.idim_ls(trace)
    out: dict[str, Any] = {
        "relative_error_pct": {
            "reference_idim_ls": ref.relative_error_pct,
            "baseline": emps.relative_error_pct(s["force_N"][cut:], s["baseline_N"][cut:]),
            "extended": emps.relative_error_pct(s["force_N"][cut:], s["extended_N"][cut:]),
        },
        "reference_parameters": ref.parameters(),
        "reference_model_misses": emps.reference_model_misses(
            result.to_json()["effects"], result.baseline_rms_N
        ),
    }
    if validation is not None:
        out["validation_relative_error_pct"] = {
            "reference_idim_ls": emps.cross_test(ref, validation).relative_error_pct,
            "baseline": emps.relative_error_pct(
                s["validation_force_N"][cut:], s["validation_baseline_N"][cut:]
            ),
            "extended": emps.relative_error_pct(
                s["validation_force_N"][cut:], s["validation_extended_N"][cut:]
            ),
        }
    return out
