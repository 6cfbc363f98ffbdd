"""Diagnosis of a fleet's traces, one job per trace, serially or on Dask.

Each trace is diagnosed on its own (its held-out blocks come from the same
trace) by the same :func:`~gms_comp.measured.diagnosis.run.diagnose` as a single trace,
so the serial and distributed paths give identical rows. A trace that cannot
be read or diagnosed gives one error row; the rest complete. The summary says
which effects recur across the fleet: a cause shared by many machines (a
guide type, a lubricant, a supplier's batch) is worth more than any one trace.
"""

from __future__ import annotations

import re
import statistics
from collections import defaultdict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

from gms_comp.app.scaleout import JobResult, run_jobs
from gms_comp.errors import TraceError
from gms_comp.gms import GmsParams

if TYPE_CHECKING:
    from gms_comp.measured.trace_clock import Segment


@dataclass(frozen=True)
class FleetJob:
    """One trace to diagnose; everything a worker needs, as plain values."""

    trace: str
    force_kind: str | None = None
    config: str | None = None
    mapping: tuple[tuple[str, str], ...] = ()
    report_dir: str | None = None  # this trace's own report folder (see report_names)
    segment: int | str | None = None  # the piece between gaps in time to read (--segment)
    table: GmsParams | None = None  # a baseline GMS to calibrate (else the free NNLS GMS)


def report_names(traces: Sequence[str]) -> list[str]:
    """One report folder name per trace, unique and safe whatever the trace names: the
    file's stem with anything but letters, digits, ``-`` and ``_`` replaced (so no
    ``..``, separator or hidden name leaves the report folder), and ``-2``, ``-3`` ...
    for a name already taken (two traces of one name in different folders)."""
    names: list[str] = []
    taken: set[str] = set()
    for trace in traces:
        stem = re.sub(r"[^A-Za-z0-9_-]+", "_", Path(trace).stem).strip("_") or "trace"
        name, k = stem, 1
        while name.lower() in taken:
            k += 1
            name = f"{stem}-{k}"
        taken.add(name.lower())
        names.append(name)
    return names


def diagnose_one(job: FleetJob) -> dict[str, Any]:
    """Diagnose one trace and return its summary row (no per-sample series)."""
    from gms_comp.measured.diagnosis.run import diagnose, load_diagnosis_config
    from gms_comp.measured.traces import ForceKind, input_json, load_trace

    segment = cast("Segment | None", job.segment)
    trace = load_trace(job.trace, dict(job.mapping) if job.mapping else None, segment=segment)
    kind = job.force_kind or trace.force_kind or "friction"
    if kind not in ("friction", "drive"):
        raise TraceError(f"{job.trace}: force kind must be friction or drive, got {kind!r}")
    config = load_diagnosis_config(job.config)
    result = diagnose(trace, cast(ForceKind, kind), None, config, job.table)
    doc = result.to_json()
    row: dict[str, Any] = {
        "trace": job.trace,
        "status": "ok",
        "force_kind": kind,
        "effect": doc["effect"],
        "parameters": doc["parameters"],
        "effects": [e["effect"] for e in doc["effects"]],
        "baseline_rms_N": doc["baseline_rms_N"],
        "extended_rms_N": doc["extended_rms_N"],
        "gain": doc["gain"],
        "baseline_source": doc["baseline"].get("source", "free_nnls"),
        "caveats": doc["caveats"],
        "input": input_json(trace),
    }
    if job.report_dir is not None:
        from gms_comp.app.report_set import input_record, write_report_set

        inputs = input_record({"trace": job.trace, "config": job.config})
        page = {**doc, "trace": job.trace, "config": job.config}
        files = write_report_set(result, job.report_dir, inputs, doc=page)
        row["report"] = [str(p) for p in files]
    return row


def diagnose_fleet(
    jobs: Sequence[FleetJob], *, client: Any | None = None, progress: bool | None = None
) -> dict[str, Any]:
    """Diagnose every job; rows keep the order of ``jobs``."""
    rows: list[dict[str, Any]] = [{} for _ in jobs]
    result: JobResult[dict[str, Any]]
    for result in run_jobs(diagnose_one, jobs, client=client, desc="diagnose", progress=progress):
        if result.ok and result.value is not None:
            rows[result.index] = result.value
        else:
            rows[result.index] = {
                "trace": jobs[result.index].trace,
                "status": "error",
                "error": result.error,
            }
    return {"traces": rows, "recurring_effects": recurring_effects(rows)}


def recurring_effects(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Effects found in more than one trace, most frequent first, with median parameters."""
    found: dict[str, list[Mapping[str, Any]]] = defaultdict(list)
    for row in rows:
        if row.get("status") == "ok" and row["effect"] not in ("none", "unknown"):
            found[row["effect"]].append(row)
    recurring = []
    for effect, hits in found.items():
        if len(hits) < 2:
            continue
        names = set.intersection(*(set(h["parameters"]) for h in hits))
        recurring.append(
            {
                "effect": effect,
                "count": len(hits),
                "share": len(hits) / len(rows),
                "traces": [h["trace"] for h in hits],
                "median_parameters": {
                    n: statistics.median(float(h["parameters"][n]) for h in hits)
                    for n in sorted(names)
                },
                "median_gain": statistics.median(float(h["gain"]) for h in hits),
            }
        )
    return sorted(recurring, key=lambda r: (-r["count"], r["effect"]))


def format_table(summary: Mapping[str, Any]) -> str:
    """The fleet summary as a plain-text table for the terminal."""
    lines = [f"{'trace':40s} {'effect':20s} {'gain':>7s}  parameters"]
    for row in summary["traces"]:
        name = Path(row["trace"]).name[:40]
        if row["status"] != "ok":
            lines.append(f"{name:40s} {'ERROR':20s} {'':>7s}  {row['error']}")
            continue
        params = ", ".join(f"{k}={v:.4g}" for k, v in row["parameters"].items())
        lines.append(f"{name:40s} {row['effect']:20s} {row['gain']:7.1%}  {params}")
        lines.extend(f"{'':40s} caveat: {c['text']}" for c in row.get("caveats", ()))
    for rec in summary["recurring_effects"]:
        lines.append(
            f"recurring: {rec['effect']} in {rec['count']} traces ({rec['share']:.0%}), "
            f"median gain {rec['median_gain']:.1%}"
        )
    return "\n".join(lines)
