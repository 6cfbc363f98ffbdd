"""Loading measured traces: canonical CSV, EMPS MATLAB files, anything through a mapping.

A trace is one sampled record of an axis: time, position and a force that is either a
friction force (a test stand's force sensor) or a drive force (force constant x current,
inertia included). Files are untrusted input: every problem raises :class:`TraceError`
with one line naming the file, the row or column and what is wrong. Sizes are checked
before anything is allocated: a CSV file's bytes and rows, a MATLAB variable's declared
shape (read with :func:`scipy.io.whosmat` before the variable is loaded). Unit slips that
can be detected (a stroke of hundreds of metres in a ``_m`` column) are refused with a
message that says what the name implies and how to map the column instead
(``--map position_m=pos_mm*0.001``): a wrong unit would only give a wrong diagnosis.

A mapping names, for each canonical column, a product of source columns (or MATLAB
variables) and numbers, e.g. ``{"force_N": "gtau*vir", "position_m": "pos_mm*0.001"}``.
Nothing is evaluated: the expression is split on ``*`` and each factor is a name or a
number.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import scipy.io

from gms_comp.atomic import atomic_path
from gms_comp.errors import TraceError
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

# Plausibility limits behind the unit-slip refusals: no linear axis this tool serves has
# a stroke above a few metres or a speed above tens of m/s.
#: Stroke of a trace's position_m column (more looks like mm or um), m.
MAX_PLAUSIBLE_STROKE_M = 5.0
#: Speed in a trace's velocity_m_s column (more looks like mm/s), m/s.
MAX_PLAUSIBLE_SPEED_M_S = 20.0
# A trace whose position never moves more than this has no motion to analyse.
MIN_MOTION_M = 1e-9

_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


class TraceUnitWarning(UserWarning):
    """Kept for callers that filter it; unit slips are now refused with a TraceError."""


@dataclass(frozen=True)
class Trace:
    """One measured record, SI units; optional columns are ``None`` when absent."""

    source: str
    time_s: np.ndarray
    position_m: np.ndarray
    force_N: np.ndarray
    velocity_m_s: np.ndarray | None = None
    reference_position_m: np.ndarray | None = None
    current_A: np.ndarray | None = None
    normal_load_N: np.ndarray | None = None
    force_kind: ForceKind | None = None  # known from the format (EMPS: drive), else None

    def __len__(self) -> int:
        return len(self.time_s)

    @property
    def sample_time_s(self) -> float:
        """Mean sampling interval (time stamps may jitter by a few ns)."""
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
        )


def parse_mapping(items: Sequence[str], where: str) -> dict[str, str]:
    """Parse ``["position_m=qm", "force_N=gtau*vir"]`` into a mapping; refuse bad entries."""
    mapping: dict[str, str] = {}
    for item in items:
        name, sep, expr = item.partition("=")
        name, expr = name.strip(), expr.strip()
        if not sep or not expr:
            raise TraceError(f"{where}: mapping entry {item!r} must read COLUMN=EXPRESSION")
        if name not in CANONICAL_COLUMNS:
            raise TraceError(
                f"{where}: mapping entry {item!r}: unknown column {name!r} "
                f"(known: {', '.join(CANONICAL_COLUMNS)})"
            )
        _factors(expr, where)
        mapping[name] = expr
    return mapping


def load_trace(
    path: str | Path,
    mapping: Mapping[str, str] | None = None,
    *,
    min_samples: int = 100,
) -> Trace:
    """Read a trace from a ``.csv`` or ``.mat`` file.

    Parameters
    ----------
    path
        The file. A CSV without ``mapping`` must hold the canonical columns; a .mat file
        without ``mapping`` must be an EMPS record (variables t, qm, vir, gtau).
    mapping
        Canonical column -> expression over the file's columns/variables (see module doc).
    min_samples
        Fewer samples than this are refused (the analysis needs them).

    Raises
    ------
    TraceError
        One line naming the file, the row/column and the problem.
    """
    p = Path(path)
    if not p.is_file():
        raise TraceError(f"{p}: file not found")
    suffix = p.suffix.lower()
    if suffix == ".csv":
        columns, lines = read_csv(p)
        mapping = mapping or _identity(columns)
        trace = _build(p, _evaluate(p, columns, mapping), None)

        def where(index: int) -> str:
            return f"row {lines[index]}"

    elif suffix == ".mat":
        declared = _declared_mat_shapes(p)
        kind: ForceKind | None = None
        if mapping is None:
            if not declared.keys() >= EMPS_VARIABLES:
                missing = ", ".join(sorted(EMPS_VARIABLES - declared.keys()))
                raise TraceError(
                    f"{p}: not an EMPS record (missing variables {missing}); "
                    "give a column mapping (--map COLUMN=VARIABLE)"
                )
            mapping = {k: v for k, v in EMPS_MAPPING.items() if v in declared or "*" in v}
            kind = "drive"
        needed = sorted(
            {f for expr in mapping.values() for f in _factors(expr, str(p)) if isinstance(f, str)}
        )
        variables = _read_mat(p, [n for n in needed if n in declared], declared)
        trace = _build(p, _evaluate(p, variables, mapping), kind)
        where = _mat_sample
    else:
        raise TraceError(f"{p}: unknown trace format {p.suffix!r} (expected .csv or .mat)")
    _validate(trace, min_samples, where, mapping)
    return trace


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
    return out


def _identity(columns: Mapping[str, np.ndarray]) -> dict[str, str]:
    return {name: name for name in CANONICAL_COLUMNS if name in columns}


def _factors(expr: str, where: str) -> list[str | float]:
    """Split ``a*b*0.001`` into names and numbers; anything else is refused."""
    out: list[str | float] = []
    for part in expr.split("*"):
        token = part.strip()
        if _NAME.fullmatch(token):
            out.append(token)
            continue
        try:
            number = float(token)
        except ValueError:
            raise TraceError(
                f"{where}: mapping {expr!r}: {token!r} is neither a column name nor a number"
            ) from None
        if not math.isfinite(number):
            raise TraceError(f"{where}: mapping {expr!r}: factor {token!r} is not finite")
        out.append(number)
    return out


def _evaluate(
    path: Path,
    columns: Mapping[str, np.ndarray],
    mapping: Mapping[str, str],
) -> dict[str, np.ndarray]:
    """Each canonical column as the product of its mapped factors."""
    for name in REQUIRED_COLUMNS:
        if name not in mapping:
            have = ", ".join(columns) or "none"
            raise TraceError(f"{path}: missing column {name!r} (columns: {have})")
    out: dict[str, np.ndarray] = {}
    for name, expr in mapping.items():
        value: np.ndarray | float = 1.0
        for factor in _factors(expr, str(path)):
            if isinstance(factor, float):
                value = value * factor
                continue
            if factor not in columns:
                raise TraceError(f"{path}: column {name}: source {factor!r} not found in file")
            data = columns[factor]
            # A 1-element MATLAB variable is a scalar (gtau); others are columns.
            value = value * (data[0] if data.size == 1 else data)
        out[name] = np.broadcast_to(np.asarray(value, dtype=float), np.shape(value)).copy()
    lengths = {n: a.size for n, a in out.items()}
    if len(set(lengths.values())) != 1 or any(a.ndim != 1 for a in out.values()):
        raise TraceError(f"{path}: columns differ in length ({lengths})")
    return out


def _build(path: Path, cols: Mapping[str, np.ndarray], kind: ForceKind | None) -> Trace:
    return Trace(source=str(path), force_kind=kind, **cols)


# --- validation --------------------------------------------------------------------------


def _mat_sample(index: int) -> str:
    return f"sample {index + 1}"


def _validate(
    trace: Trace,
    min_samples: int,
    where: Callable[[int], str],
    mapping: Mapping[str, str],
) -> None:
    src = trace.source
    n = len(trace)
    if n < min_samples:
        raise TraceError(f"{src}: {n} samples, the analysis needs at least {min_samples}")
    for name in CANONICAL_COLUMNS:
        values = getattr(trace, name)
        if values is None:
            continue
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise TraceError(f"{src}: {where(bad[0])}, column {name}: value is not finite")
    steps = np.diff(trace.time_s)
    bad = np.flatnonzero(steps <= 0)
    if bad.size:
        i = bad[0]
        raise TraceError(
            f"{src}: {where(i + 1)}, column time_s: time does not increase "
            f"({trace.time_s[i]:.9g} -> {trace.time_s[i + 1]:.9g} s)"
        )
    stroke = float(np.ptp(trace.position_m))
    if stroke < MIN_MOTION_M:
        raise TraceError(f"{src}: column position_m: no motion (stroke {stroke:.3g} m)")
    if stroke > MAX_PLAUSIBLE_STROKE_M:
        micro = stroke > 1e3 * MAX_PLAUSIBLE_STROKE_M
        raise TraceError(
            src,
            "column position_m",
            f"spans {stroke:.4g} m, more than the {MAX_PLAUSIBLE_STROKE_M:g} m stroke of any "
            f"axis served: it looks like {'um' if micro else 'mm'} although the name says "
            "metres; map the column with its scale, e.g. "
            f"--map position_m={_scaled(mapping, 'position_m', 1e-6 if micro else 1e-3)}",
        )
    if trace.velocity_m_s is not None:
        speed = float(np.max(np.abs(trace.velocity_m_s)))
        if speed > MAX_PLAUSIBLE_SPEED_M_S:
            raise TraceError(
                src,
                "column velocity_m_s",
                f"reaches {speed:.4g} m/s, more than the {MAX_PLAUSIBLE_SPEED_M_S:g} m/s of "
                "any axis served: it looks like mm/s although the name says m/s; map the "
                f"column with its scale, e.g. "
                f"--map velocity_m_s={_scaled(mapping, 'velocity_m_s', 1e-3)}",
            )
        if float(np.ptp(trace.velocity_m_s)) == 0.0:
            raise TraceError(
                src,
                "column velocity_m_s",
                f"is constant ({trace.velocity_m_s[0]:g} m/s) while the position moves "
                f"{stroke:.3g} m: not a velocity signal; map the right column or leave it out",
            )


def _scaled(mapping: Mapping[str, str], column: str, factor: float) -> str:
    """The mapping expression of ``column`` times ``factor``, for a suggestion."""
    return f"{mapping.get(column, column)}*{factor:g}"
