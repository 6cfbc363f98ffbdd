"""Loading measured traces: canonical CSV, EMPS MATLAB files, anything through a mapping.

A trace is one sampled record of an axis: time, position and a force that is either a
friction force (a test stand's force sensor) or a drive force (force constant x current,
inertia included). Files are untrusted input: every problem raises :class:`TraceError`
with one line naming the file, the row or column and what is wrong, before any analysis.
Loading runs one chain of checks (docs/traces.md):

1. sizes before parsing: a CSV file's bytes and rows (:mod:`.trace_csv`), a MATLAB
   variable's declared shape (read with :func:`scipy.io.whosmat` before it is loaded);
2. the mapping: each canonical column as an expression over the file's columns
   (:mod:`.trace_map`; ``{"force_N": "gtau*vir", "position_m": "\"pos (um)\"*1e-6"}``),
   never evaluated by Python; a missing column names the header and the ``--map`` to give;
3. finite values, with their row;
4. the clock (:mod:`.trace_clock`): increasing stamps, a sample rate some axis log has,
   gaps refused or a segment chosen, a non-uniform clock resampled and said so
   (:attr:`Trace.clock`);
5. units by physics (:mod:`.trace_units`): stroke, speed, acceleration, resolution and
   force against what a ball-guided axis does, refused with the unit it looks like and
   the ``--map`` that scales it.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import scipy.io

from gms_comp.atomic import atomic_path
from gms_comp.errors import TraceError
from gms_comp.measured import trace_map, trace_units
from gms_comp.measured.trace_clock import Clock, Segment, read_clock
from gms_comp.measured.trace_csv import read_csv
from gms_comp.validation import MAX_TRACE_SAMPLES

ForceKind = Literal["friction", "drive"]

REQUIRED_COLUMNS = ("time_s", "position_m", "force_N")
OPTIONAL_COLUMNS = ("velocity_m_s", "reference_position_m", "current_A", "normal_load_N")
CANONICAL_COLUMNS = REQUIRED_COLUMNS + OPTIONAL_COLUMNS

# The EMPS benchmark's variables (Janot, Gautier, Brunot 2019): force = gtau * vir.
EMPS_VARIABLES = frozenset({"t", "qm", "vir", "gtau"})
EMPS_MAPPING: Mapping[str, str] = {
    "time_s": "t",
    "position_m": "qm",
    "force_N": "gtau*vir",
    "reference_position_m": "qg",
}


@dataclass(frozen=True)
class Trace:
    """One measured record, SI units; optional columns are ``None`` when absent.

    A loaded trace is on a uniform clock (:attr:`clock` says how its stamps were read);
    one made in memory is taken as it is.
    """

    source: str
    time_s: np.ndarray
    position_m: np.ndarray
    force_N: np.ndarray
    velocity_m_s: np.ndarray | None = None
    reference_position_m: np.ndarray | None = None
    current_A: np.ndarray | None = None
    normal_load_N: np.ndarray | None = None
    force_kind: ForceKind | None = None  # known from the format (EMPS: drive), else None
    clock: Clock | None = None  # how the file's time stamps were read (None: in memory)

    def __len__(self) -> int:
        return len(self.time_s)

    @property
    def commanded_or_measured_position_m(self) -> np.ndarray:
        """The commanded position where the trace holds it on every sample, else the
        measured one: the path a closed-loop axis follows without its ringing."""
        ref = self.reference_position_m
        return ref if ref is not None and bool(np.all(np.isfinite(ref))) else self.position_m

    @property
    def sample_time_s(self) -> float:
        """Mean sampling interval (the clock is uniform; stamps may jitter by a few ns)."""
        return float((self.time_s[-1] - self.time_s[0]) / (len(self.time_s) - 1))

    def slice(self, start: int, stop: int) -> Trace:
        """The samples ``start:stop`` as a trace of their own."""

        def cut(a: np.ndarray | None) -> np.ndarray | None:
            return None if a is None else a[start:stop]

        return Trace(
            source=f"{self.source}[{start}:{stop}]",
            time_s=self.time_s[start:stop],
            position_m=self.position_m[start:stop],
            force_N=self.force_N[start:stop],
            velocity_m_s=cut(self.velocity_m_s),
            reference_position_m=cut(self.reference_position_m),
            current_A=cut(self.current_A),
            normal_load_N=cut(self.normal_load_N),
            force_kind=self.force_kind,
            clock=self.clock,
        )


def parse_mapping(items: Sequence[str], where: str) -> dict[str, str]:
    """Parse ``["position_m=qm", "force_N=gtau*vir"]`` into a mapping; refuse bad entries.

    The expressions are parsed when the file is read (a header name may hold any
    character, so only the file's header tells a name from an operator); here each entry
    is checked for its form, its canonical column and its length.
    """
    mapping: dict[str, str] = {}
    for item in items:
        name, sep, expr = item.partition("=")
        name, expr = name.strip(), expr.strip()
        if not sep or not expr:
            raise TraceError(where, "", f"mapping entry {item!r} must read COLUMN=EXPRESSION")
        if name not in CANONICAL_COLUMNS:
            raise TraceError(
                where, "",
                f"mapping entry {item!r}: unknown column {name!r} "
                f"(known: {', '.join(CANONICAL_COLUMNS)})",
            )  # fmt: skip
        if name in mapping:
            raise TraceError(where, "", f"column {name} is mapped twice")
        if len(expr) > trace_map.MAX_MAP_CHARS or not expr.isprintable():
            raise TraceError(
                where, "", f"mapping entry {item[:40]!r}...: at most "
                f"{trace_map.MAX_MAP_CHARS} printable characters",
            )  # fmt: skip
        mapping[name] = expr
    return mapping


# A sidecar is small (a recording's is about 1 kB): a larger file is not one.
MAX_SIDECAR_BYTES = 1 << 16


def sidecar_force_kind(path: Path) -> ForceKind | None:
    """The force kind a CSV's JSON sidecar (``OUT.csv.json``, as ``gms-comp record`` writes
    it) declares under ``force_kind``, or None where there is none (or it says nothing
    this reader knows: the sidecar is a hint, the CSV the data)."""
    sidecar = path.with_name(path.name + ".json")
    try:
        if not sidecar.is_file() or sidecar.stat().st_size > MAX_SIDECAR_BYTES:
            return None
        doc = json.loads(sidecar.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    kind = doc.get("force_kind") if isinstance(doc, dict) else None
    return "drive" if kind == "drive" else "friction" if kind == "friction" else None


def load_trace(
    path: str | Path,
    mapping: Mapping[str, str] | None = None,
    *,
    min_samples: int = 100,
    segment: Segment | None = None,
) -> Trace:
    """Read a trace from a ``.csv`` or ``.mat`` file.

    Parameters
    ----------
    path
        The file. A CSV without ``mapping`` must hold the canonical columns; a .mat file
        without ``mapping`` must be an EMPS record (variables t, qm, vir, gtau).
    mapping
        Canonical column -> expression over the file's columns/variables
        (:mod:`.trace_map`); columns not named keep the file's column of their name.
    min_samples
        Fewer samples than this are refused (the analysis needs them).
    segment
        With gaps in time, which piece between them to read (1-based, or ``"longest"``);
        None refuses a trace with gaps.

    Raises
    ------
    TraceError
        One line naming the file, the row/column and the problem.
    """
    p = Path(path)
    if not p.is_file():
        raise TraceError(str(p), "", "file not found" if not p.exists() else "not a file")
    suffix = p.suffix.lower()
    kind: ForceKind | None = None
    if suffix == ".csv":
        kind = sidecar_force_kind(p)
        columns, lines = read_csv(p)
        mapping = {**_identity(columns), **(mapping or {})}
        parsed = _parsed(p, mapping, columns)

        def where(index: int) -> str:
            return f"row {lines[index]}"

    elif suffix == ".mat":
        declared = _declared_mat_shapes(p)
        if mapping is None:
            if not declared.keys() >= EMPS_VARIABLES:
                missing = ", ".join(sorted(EMPS_VARIABLES - declared.keys()))
                raise TraceError(
                    f"{p}: not an EMPS record (missing variables {missing}); "
                    "give a column mapping (--map COLUMN=VARIABLE)"
                )
            mapping = {k: v for k, v in EMPS_MAPPING.items() if v in declared or "*" in v}
            kind = "drive"
        parsed = _parsed(p, mapping, declared)
        needed = sorted(set().union(*(trace_map.sources(n) for n in parsed.values())))
        columns = _read_mat(p, needed, declared)
        where = _mat_sample
    else:
        raise TraceError(f"{p}: unknown trace format {p.suffix!r} (expected .csv or .mat)")
    values = _evaluate(p, columns, parsed)
    _check_samples(str(p), len(values["time_s"]), min_samples)
    _check_finite(str(p), values, where)
    reading = read_clock(values["time_s"], str(p), where, mapping["time_s"], segment)
    cut = {name: v[reading.start : reading.stop] for name, v in values.items()}
    if reading.grid_s is not None:
        cut = {name: np.interp(reading.grid_s, cut["time_s"], v) for name, v in cut.items()}
        cut["time_s"] = reading.grid_s
    trace = Trace(source=str(p), force_kind=kind, clock=reading.clock, **cut)
    _check_samples(str(p), len(trace), min_samples)
    _check_units(trace, mapping)
    return trace


def input_json(trace: Trace) -> dict[str, Any]:
    """How a trace was read, for the diagnosis JSON's ``input``: its samples and clock
    (``resampled_from_Hz``, ``segment``), the motion's figures that its units are checked
    by, and, when not used as recorded, a ``note``."""
    dt = trace.sample_time_s
    doc: dict[str, Any] = {"samples": len(trace), "sample_rate_Hz": 1.0 / dt}
    if trace.clock is not None:
        doc.update(trace.clock.to_json())
    doc.update(
        stroke_m=float(np.ptp(trace.position_m)),
        top_speed_m_s=trace_units.peak_speed(trace.position_m, dt),
        top_acceleration_m_s2=trace_units.peak_acceleration(trace.position_m, dt),
    )
    if trace.clock is not None and (note := trace.clock.describe()):
        doc["note"] = note
    return doc


def write_trace(path: str | Path, trace: Trace) -> None:
    """Write ``trace`` as canonical CSV (only the columns it holds)."""
    names = [n for n in CANONICAL_COLUMNS if getattr(trace, n) is not None]
    data = np.column_stack([getattr(trace, n) for n in names])
    with atomic_path(path) as tmp:
        np.savetxt(tmp, data, delimiter=",", header=",".join(names), comments="", fmt="%.12g")


# --- reading -----------------------------------------------------------------------------


def _declared_mat_shapes(path: Path) -> dict[str, tuple[int, ...]]:
    """Each variable's declared shape, read from the file's headers before any data."""
    try:
        listing = scipy.io.whosmat(str(path))
    except NotImplementedError:  # scipy's signal for an HDF5-based v7.3 file
        raise TraceError(f"{path}: MATLAB v7.3 files are not supported; save with -v7") from None
    except Exception as err:  # scipy raises many kinds on a corrupt header
        raise TraceError(
            f"{path}: not a readable MATLAB file ({type(err).__name__}: {err})"
        ) from None
    return {name: tuple(int(d) for d in shape) for name, shape, _cls in listing}


def _read_mat(
    path: Path, names: Sequence[str], declared: Mapping[str, tuple[int, ...]]
) -> dict[str, np.ndarray]:
    """The numeric variables ``names`` of a MATLAB file (v4-v7), sizes checked first.

    A variable must be a vector (or a 1x1 scalar such as EMPS's ``gtau``) of at most
    :data:`~gms_comp.validation.MAX_TRACE_SAMPLES` elements by its declared shape.
    """
    for name in names:
        shape = declared[name]
        size = math.prod(shape)
        if size > MAX_TRACE_SAMPLES:
            dims = "x".join(map(str, shape))
            raise TraceError(
                str(path),
                f"variable {name}",
                f"declares {dims} = {size} elements, more than the {MAX_TRACE_SAMPLES} "
                "samples a trace may have (checked before loading)",
            )
        if sum(d > 1 for d in shape) > 1:
            dims = "x".join(map(str, shape))
            raise TraceError(
                str(path),
                f"variable {name}",
                f"is a {dims} matrix, a trace variable must be a vector; save each "
                "channel as its own vector and map it (--map COLUMN=VARIABLE)",
            )
    if not names:
        return {}
    try:
        raw = scipy.io.loadmat(str(path), variable_names=list(names))
    except NotImplementedError:
        raise TraceError(f"{path}: MATLAB v7.3 files are not supported; save with -v7") from None
    except Exception as err:  # a corrupt body after a readable header
        raise TraceError(
            f"{path}: not a readable MATLAB file ({type(err).__name__}: {err})"
        ) from None
    out: dict[str, np.ndarray] = {}
    for name, value in raw.items():
        if name.startswith("__") or not isinstance(value, np.ndarray):
            continue
        if value.dtype.kind in "biuf":
            out[name] = np.asarray(value, dtype=float).ravel()
    for name in names:
        if name not in out:
            raise TraceError(str(path), f"variable {name}", "is not numeric")
    return out


def _identity(columns: Collection[str]) -> dict[str, str]:
    return {name: trace_map.quoted(name) for name in CANONICAL_COLUMNS if name in columns}


def _parsed(
    path: Path, mapping: Mapping[str, str], names: Collection[str]
) -> dict[str, trace_map.Node]:
    """Each mapped column's expression, parsed against the file's column names; a
    required column neither in the file nor mapped is refused with the header."""
    for name in REQUIRED_COLUMNS:
        if name not in mapping:
            raise TraceError(str(path), "", _missing(name, names, mapping))
    return {
        name: trace_map.parse(expr, names, f"{path}: --map {name}={expr}")
        for name, expr in mapping.items()
    }


def _missing(name: str, names: Collection[str], mapping: Mapping[str, str]) -> str:
    header = ", ".join(names) or "none"
    used = set(mapping.values())
    spare = [n for n in names if trace_map.quoted(n) not in used]
    example = f", e.g. --map '{name}={trace_map.quoted(spare[0])}'" if spare else ""
    return (
        f"missing column {name!r} (the file's columns: {header}); name the column that holds "
        f"it with --map {name}=EXPRESSION{example}"
    )


def _evaluate(
    path: Path, columns: Mapping[str, np.ndarray], parsed: Mapping[str, trace_map.Node]
) -> dict[str, np.ndarray]:
    """Each canonical column from its expression, as a 1-d float array."""
    out: dict[str, np.ndarray] = {}
    for name, node in parsed.items():
        value = trace_map.evaluate(node, columns)
        out[name] = np.array(value, dtype=float, ndmin=1)
    lengths = {n: a.size for n, a in out.items()}
    if len(set(lengths.values())) != 1 or any(a.ndim != 1 for a in out.values()):
        raise TraceError(f"{path}: columns differ in length ({lengths})")
    return out


# --- validation --------------------------------------------------------------------------


def _mat_sample(index: int) -> str:
    return f"sample {index + 1}"


def _check_samples(src: str, n: int, min_samples: int) -> None:
    if n < min_samples:
        raise TraceError(f"{src}: {n} samples, the analysis needs at least {min_samples}")


def _check_finite(src: str, values: Mapping[str, np.ndarray], where: Callable[[int], str]) -> None:
    for name, column in values.items():
        bad = np.flatnonzero(~np.isfinite(column))
        if bad.size:
            raise TraceError(f"{src}: {where(int(bad[0]))}, column {name}: value is not finite")


def _check_units(trace: Trace, mapping: Mapping[str, str]) -> None:
    src = trace.source
    trace_units.check_position(trace.position_m, trace.sample_time_s, src, mapping["position_m"])
    if trace.velocity_m_s is not None:
        trace_units.check_velocity(trace.velocity_m_s, src, mapping["velocity_m_s"])
        if float(np.ptp(trace.velocity_m_s)) == 0.0:
            raise TraceError(
                src,
                "column velocity_m_s",
                f"is constant ({trace.velocity_m_s[0]:g} m/s) while the position moves "
                f"{float(np.ptp(trace.position_m)):.3g} m: not a velocity signal; map the "
                "right column or leave it out",
            )
    trace_units.check_force(trace.force_N, src, mapping["force_N"])
