"""``gms-comp diagnose``: where the model is wrong on a measured trace, the cause, the gain.

Without ``--json`` a progress line on stderr, then a readable summary on stdout: where the
baseline is wrong by motion phase, the cause and its parameters with units, the gain and
the files written. With ``--json`` the result as JSON on stdout and nothing else there.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from gms_comp.app import emps
from gms_comp.app.fleet import FleetJob, diagnose_fleet, format_table, report_names
from gms_comp.app.report_set import input_record, write_report_set
from gms_comp.app.scaleout import add_cluster_arguments, cli_client
from gms_comp.arguments import input_file, output_file, replaced_dir
from gms_comp.atomic import SET_MANIFEST, write_text
from gms_comp.config import config_hash, default_config_path, read_toml
from gms_comp.errors import GmsCompError
from gms_comp.gms import GmsParams
from gms_comp.measured.diagnosis.phases import phase_label
from gms_comp.measured.diagnosis.result import parameter_text
from gms_comp.measured.diagnosis.run import Diagnosis, diagnose, load_diagnosis_config
from gms_comp.measured.trace_clock import segment_choice
from gms_comp.measured.traces import Trace, input_json, load_trace, parse_mapping
from gms_comp.physics.config import load_ball_config
from gms_comp.runtime.effects import effect_to_dict
from gms_comp.tables.reduction import reduce_to_gms
from gms_comp.tables.table import Extension, Fidelity, GmsTable, read_table, write_table

COLUMNS_HELP = (
    "A canonical CSV has a header row and one sample per row, SI units: time_s (s, strictly "
    "increasing), position_m (m) and force_N (N) are required; velocity_m_s, "
    "reference_position_m, current_A and normal_load_N are optional. EMPS .mat files "
    "(variables t, qm, qg, vir, gtau) are read directly; any other .csv/.mat with --map. "
    "Time stamps: jitter within 10 % of the step, or stamps within a quarter step of one "
    "uniform clock, are read on that clock; missing samples, a change of rate or stamps "
    "further off are resampled onto a uniform clock (the "
    "summary and the JSON's input.resampled_from_Hz say so); a gap of more than 4 steps "
    "is refused unless --segment picks a piece; a repeated stamp is refused. Units are "
    "checked by physics (sample rate, stroke, speed, acceleration, force): a trace in ms, "
    "mm or kN is refused with the --map that scales it. See docs/traces.md."
)
MAP_HELP = (
    "column mapping COLUMN=EXPRESSION (repeatable): the expression combines the file's "
    "columns and numbers with + - * / and parentheses, e.g. position_m=pos_mm*0.001 or "
    "force_N=gtau*vir; header names are written as they are (time_s=t[ms]*0.001) or in "
    "double quotes ('position_m=\"pos (um)\"*1e-6'); nothing is evaluated by Python"
)


def register(subparsers: Any) -> None:
    """Add the ``diagnose`` subcommand to ``subparsers``."""
    p = subparsers.add_parser(
        "diagnose",
        help="diagnose measured traces against the model",
        description=(
            "Diagnose one trace, or a fleet of traces in parallel on Dask (a local cluster, "
            "or an existing one with --scheduler): the named effect, its parameters and "
            "the gain per trace, and the effects that recur across the fleet. " + COLUMNS_HELP
        ),
    )
    p.add_argument(
        "traces",
        nargs="+",
        metavar="TRACE",
        type=input_file,
        help="canonical CSV, EMPS .mat, or any .csv/.mat with --map",
    )
    add_cluster_arguments(p)
    p.add_argument(
        "--config",
        type=input_file,
        help=(
            "config file: [diagnosis] section; with [bearing] and [stand] sections its ball "
            "model is reduced to a GMS table, calibrated as the baseline"
        ),
    )
    p.add_argument(
        "--table-in",
        metavar="TABLE",
        type=input_file,
        help="GMS table to calibrate as the baseline (its level, presliding, velocity level)",
    )
    p.add_argument(
        "--force-kind",
        choices=("friction", "drive"),
        help="what force_N is (default: drive for EMPS files, else friction)",
    )
    p.add_argument(
        "--validate",
        metavar="TRACE2",
        type=input_file,
        help="held-out trace (else blocks of TRACE)",
    )
    p.add_argument("--map", action="append", default=[], metavar="COLUMN=EXPR", help=MAP_HELP)
    p.add_argument(
        "--segment",
        type=segment_choice,
        metavar="N|longest",
        help="with gaps in time, diagnose the N-th piece between them (or the longest)",
    )
    p.add_argument(
        "--json", action="store_true", help="print the result as JSON on stdout (only that)"
    )
    p.add_argument(
        "--report",
        metavar="DIR",
        type=replaced_dir,
        help="write plots, index.html and the extended table into this folder",
    )
    p.add_argument(
        "--table", metavar="OUT", type=output_file, help="write the extended model as a GMS table"
    )
    p.add_argument(
        "--closed-loop",
        nargs="?",
        const=default_config_path(),  # a Path: argparse passes it on as it is
        type=input_file,
        metavar="SCENARIO",
        help=(
            "simulate the axis with the diagnosed friction and compare the compensator with "
            "the baseline and the extended model (scenario config; default: Table 1's)"
        ),
    )
    p.set_defaults(func=run)


@contextmanager
def _progress(enabled: bool) -> Iterator[Callable[[str], None]]:
    """A status line on stderr (only on a terminal) fed with the diagnosis's steps."""
    bar = tqdm(total=None, desc="diagnose", bar_format="{desc} [{elapsed}]", file=sys.stderr,
               disable=None if enabled else True, leave=False)  # fmt: skip
    try:
        yield lambda msg: bar.set_description_str(f"diagnose: {msg}")
    finally:
        bar.close()


def run(args: argparse.Namespace) -> int:
    """Diagnose one trace (or a fleet) and report."""
    mapping = parse_mapping(args.map, "--map") if args.map else None
    if len(args.traces) > 1 or args.scheduler or args.cluster_config:
        return _run_fleet(args, mapping)
    args.trace = args.traces[0]
    trace = load_trace(args.trace, mapping, segment=args.segment)
    validation = load_trace(args.validate, mapping, segment=args.segment) if args.validate else None
    kind = args.force_kind or trace.force_kind or "friction"
    config = load_diagnosis_config(args.config)
    with _progress(True) as say:
        result = diagnose(trace, kind, validation, config, _baseline_table(args), say)
    doc = result.to_json()
    doc["trace"] = str(args.trace)
    doc["input"] = input_json(trace)
    if validation is not None:
        doc["validation_input"] = input_json(validation)
    doc["config"] = args.config
    if trace.force_kind == "drive" and kind == "drive":
        doc.update(_benchmark_errors(trace, validation, result))
    if args.closed_loop is not None:
        from gms_comp.app.commands.diagnose_closed_loop import (
            closed_loop_gain,  # the simulated axis when asked
        )

        doc["closed_loop"] = closed_loop_gain(result, args.closed_loop)
    written: list[str] = []
    if args.report:
        files = write_report_set(
            result,
            args.report,
            _inputs(args),
            extended_table(result, args.trace),
            args.table,
            doc,
        )
        doc["table"] = str(files[0])
        doc["report"] = [str(p) for p in files[1:]]
        written = [str(p) for p in files]
    elif args.table:
        write_table(args.table, extended_table(result, args.trace))
        doc["table"] = str(args.table)
        written.append(str(args.table))
    if args.json:
        sys.stdout.write(json.dumps(doc, indent=2) + "\n")
        for path in written:
            print(f"wrote {path}", file=sys.stderr)
    else:
        print(summary(doc, len(trace), kind))
        for path in written:
            print(f"wrote {path}")
    return 0


def summary(doc: Mapping[str, Any], samples: int, kind: str) -> str:
    """The diagnosis JSON as a short text for people."""
    b = doc["baseline"]
    lines = [
        f"diagnosis of {doc['trace']} ({samples} samples{_every(b)}, {kind} force), "
        f"{doc['seconds']:.1f} s",
        f"baseline: {b['model'].replace('_', ' ')}, sliding force {b['sliding_force_N']:.4g} N, "
        f"slip level C_v {b['slip_level']:.3g}"
        f"{' (the stick limit follows it)' if b.get('limit_follows_level') else ''}, "
        f"held-out RMS {doc['baseline_rms_N']:.4g} N "
        f"(noise {doc['noise_rms_N']:.3g} N)",
    ]
    for key, what in (("input", "input"), ("validation_input", "validation input")):
        if key in doc:
            lines.append(f"{what}: {_input_text(doc[key])}")
    if b.get("position") == "encoder counts read as motion":
        lines.append(
            f"position: the encoder's counts read as motion (a count moves the model "
            f"{b['encoder_noise_ratio']:.2g} x the force noise)"
        )
    lines.append("where the baseline is wrong (residual RMS by motion phase):")
    phases = sorted(doc["phases"].items(), key=lambda kv: -kv[1]["rms_N"])
    for key, ph in phases[:6]:
        lines.append(
            f"  {phase_label(key):34s} {ph['rms_N']:9.4g} N  (mean {ph['mean_N']:+.3g} N, "
            f"{ph['fraction']:.0%} of samples)"
        )
    effect = doc["effect"]
    if effect == "unknown":
        lines.append("cause: unknown - no catalogue effect explains what is left: "
                     + doc["structure"]["description"])  # fmt: skip
        if doc["effects"]:
            lines.append("  partial candidates: " + ", ".join(e["effect"] for e in doc["effects"]))
    elif effect == "none":
        lines.append("cause: none - the baseline explains the trace down to noise-like residual")
    for i, e in enumerate(doc["effects"]):
        params = ", ".join(parameter_text(k, v) for k, v in e["parameters"].items())
        head = "cause" if i == 0 and effect != "unknown" else "  then"
        lines.append(f"{head}: {e['effect']} ({params})")
        if e.get("in_context"):
            figures = ", ".join(parameter_text(k, v) for k, v in e["in_context"].items())
            lines.append(f"        along this trace: {figures}")
        if e.get("intervals_95"):
            lines.append(f"        95 % intervals: {_intervals(e)}")
    level = doc.get("extended_slip_level", b["slip_level"])
    base_law = b.get("limit_follows_level", False)
    law = doc.get("extended_limit_follows_level", base_law)
    tail = doc.get("extended_transition_tail", b.get("transition_tail"))
    moved = abs(level - b["slip_level"]) > 0.005 or law != base_law
    if doc["effects"] and (moved or tail != b.get("transition_tail")):
        follows = (
            f", its stick limit {'following' if law else 'not following'} it"
            if law != base_law
            else ""
        )
        if tail != b.get("transition_tail"):
            approach = "exponential" if tail is None else f"rational (tail {tail:g})"
            follows += f", reached on the {approach} approach"
        lines.append(
            f"  with the slip level C_v {level:.3g}{follows} (the GMS alone: {b['slip_level']:.3g})"
        )
    for caveat in doc.get("caveats", ()):
        lines.append(f"caveat: {caveat['text']}")
    limits = doc.get("detection_limits") or {}
    if limits:
        lines.append(
            "smallest effects this trace would have revealed (what it rules out where none "
            "is named):"
        )
        for name, figures in limits.items():
            lines.append(f"  {name}: {_limit(name, figures, doc)}")
    lines.append(
        f"gain: {doc['gain']:.1%} (held-out RMS {doc['baseline_rms_N']:.4g} N -> "
        f"{doc['extended_rms_N']:.4g} N)"
    )
    for name, pct in (
        ("train", doc.get("relative_error_pct")),
        ("cross-test", doc.get("validation_relative_error_pct")),
    ):
        if pct:
            lines.append(
                f"EMPS {name} relative error: extended {pct['extended']:.2f} %, baseline "
                f"{pct['baseline']:.2f} %, IDIM-LS reference {pct['reference_idim_ls']:.2f} %"
            )
    return "\n".join(lines)


def _inputs(args: argparse.Namespace) -> dict[str, Any]:
    """The run's input files, each with its path and SHA-256 (named by the report)."""
    return input_record(
        {
            "trace": args.trace,
            "validate": args.validate,
            "config": args.config,
            "table_in": args.table_in,
            "closed_loop": args.closed_loop,
        }
    )


def _intervals(entry: Mapping[str, Any]) -> str:
    """An effect's 95 % intervals as text, those that reach a bound said so."""
    bounded = set(entry.get("interval_at_bound", ()))
    parts = []
    for name, (lo, hi) in entry["intervals_95"].items():
        low, high = parameter_text(name, lo), parameter_text(name, hi)
        text = f"{low.split(' = ')[0]} {low.split(' = ')[1]} to {high.split(' = ')[1]}"
        parts.append(text + (" (reaches its bound: the trace does not pin it down)"
                             if name in bounded else ""))  # fmt: skip
    return ", ".join(parts)


def _limit(name: str, figures: Mapping[str, float], doc: Mapping[str, Any]) -> str:
    """One effect's detection limit as text: the figure it is told in, its range over the
    shapes tried, what to record to see smaller ones."""
    span = (doc.get("detection_limits_range") or {}).get(name, {})
    told = str(next(iter(span), ""))
    text = parameter_text(told, figures[told]) if told in figures else ""
    lo, hi = span.get(told, (0.0, 0.0))
    if hi > 1.01 * lo:
        text += f" ({lo:.3g} to {hi:.3g} over the shapes tried)"
    hint = (doc.get("to_see_smaller") or {}).get(name)
    return text + (f"; to see smaller: {hint}" if hint else "")


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
    names = report_names(args.traces)
    jobs = [
        FleetJob(
            trace=str(path),
            force_kind=args.force_kind,
            config=args.config,
            mapping=tuple(sorted(mapping.items())) if mapping else (),
            segment=args.segment,
            report_dir=str(Path(args.report) / name) if args.report else None,
            table=table,
        )
        for path, name in zip(args.traces, names, strict=True)
    ]
    if args.serial:
        fleet = diagnose_fleet(jobs)
    else:
        with cli_client(args) as client:
            fleet = diagnose_fleet(jobs, client=client)
    written = [p for row in fleet["traces"] for p in row.get("report", [])]
    if args.report:  # the overview page, then the fleet's index, written last
        from gms_comp.app.report import write_overview  # matplotlib only when asked for

        written.append(str(write_overview(fleet, args.report, names)))
        index = {"format": "gms-comp-fleet-report", "version": 1, "traces": [
            {k: row.get(k) for k in ("trace", "status", "report")} for row in fleet["traces"]
        ]}  # fmt: skip
        written.append(str(write_text(Path(args.report) / SET_MANIFEST, json.dumps(index) + "\n")))
    if args.json:
        sys.stdout.write(json.dumps(fleet, indent=2) + "\n")
    else:
        print(format_table(fleet))
    for path in written:
        print(f"wrote {path}", file=sys.stderr if args.json else sys.stdout)
    return 0 if all(row["status"] == "ok" for row in fleet["traces"]) else 1


def extended_table(result: Diagnosis, trace_path: str | Path) -> GmsTable:
    """The diagnosed model as a GMS table with its extensions (its force: the axis's)."""
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
        extension_context=result.extension_context or None,
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


def _input_text(doc: Mapping[str, Any]) -> str:
    """The trace's clock and motion figures (a unit slip shows in them), and how its
    time stamps were read when not as recorded."""
    text = (
        f"{doc['sample_rate_Hz']:.6g} Hz, stroke {doc['stroke_m']:.4g} m, top speed "
        f"{doc['top_speed_m_s']:.4g} m/s, top acceleration {doc['top_acceleration_m_s2']:.4g} m/s^2"
    )
    return f"{text}; {doc['note']}" if doc.get("note") else text


def _every(baseline: Mapping[str, Any]) -> str:
    """How many of the samples were fitted, if not all."""
    every = int(baseline.get("fitted_every", 1))
    return f", 1 in {every} fitted (fit_rate_Hz)" if every > 1 else ""
