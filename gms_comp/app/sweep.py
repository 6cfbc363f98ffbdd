"""Table families: one GMS table per point of a grid over config keys.

A sweep file names a base config, the number of elements and the axes::

    [sweep]
    base_config = "table1.toml"   # relative to the sweep file; default: the packaged Table 1
    elements = 16

    [sweep.axes]
    "stand.ball_loads_N" = [25.0, 50.0, 100.0]   # a number for an array key sets every entry
    "bearing.ball_radius_m" = [3.0e-3, 3.175e-3]

Every point is written as a complete config (``points/NNNN.toml``, the sweep's
``elements`` in its ``[table]``): its whole effective config, validated by the same
loader as any config, so an invalid point is reported with the file, key and reason
while the other points complete. A point whose table exists and was made from identical
config bytes (its ``source.sha256``) is not computed again: a run that stopped (or whose
worker died) resumes where it was, and a point whose config changed (another base config,
axis value or ``elements``) is computed again, its row saying so. Each table names the
hash of the config it was made from; the manifest, which lists every point with its
config's hash, is rewritten every few seconds and last at the end (also when
interrupted).

A sweep file says what to compute, never where: a ``[scaleout]`` section (a scheduler
address, TLS files) is refused. Dask runs what its scheduler sends, so the scheduler and
its certificates come from the command line (``--scheduler``, ``--tls-*``,
``--cluster-config``) only.
"""

from __future__ import annotations

import copy
import dataclasses
import itertools
import json
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from gms_comp import __version__
from gms_comp.app.scaleout import JobResult, run_jobs
from gms_comp.atomic import write_bytes, write_text
from gms_comp.config import config_hash, default_config_path, read_toml
from gms_comp.errors import ConfigError, TableError
from gms_comp.physics.config import load_ball_config
from gms_comp.tables.table import GmsTable, read_table, write_table
from gms_comp.validation import (
    MAX_SWEEP_POINTS,
    MAX_TABLE_BYTES,
    parse_json,
    read_text,
    read_toml_document,
)

MANIFEST = "manifest.json"
FAMILY_FORMAT = "gms-comp-family"
FAMILY_VERSION = 1
MANIFEST_INTERVAL_S = 2.0
#: Elements of each table of a sweep (``[sweep] elements``).
MAX_SWEEP_ELEMENTS = 256


@dataclass(frozen=True)
class SweepSpec:
    """A parsed sweep file: base config, element count and the grid axes."""

    path: str
    base_config: Path
    elements: int
    axes: tuple[tuple[str, tuple[Any, ...]], ...]

    def grid(self) -> list[dict[str, Any]]:
        """Every point of the grid, as ``{dotted key: value}``, last axis fastest."""
        keys = [k for k, _ in self.axes]
        return [
            dict(zip(keys, combo, strict=True))
            for combo in itertools.product(*(v for _, v in self.axes))
        ]


def load_sweep(path: str | Path) -> SweepSpec:
    """Read and check a sweep file (errors name the file and the key)."""
    p = Path(path)
    doc = read_toml_document(p, error=ConfigError)
    if "scaleout" in doc:
        raise ConfigError(
            str(p), "scaleout", "a sweep file may not say where code runs: give the scheduler "
            "on the command line (--scheduler and --tls-*, or --cluster-config YOUR.toml)",
        )  # fmt: skip
    sweep = doc.get("sweep")
    if not isinstance(sweep, dict) or set(doc) != {"sweep"}:
        raise ConfigError(str(p), "sweep", "a sweep file holds one [sweep] table")
    unknown = set(sweep) - {"base_config", "elements", "axes"}
    if unknown:
        raise ConfigError(
            str(p),
            f"sweep.{sorted(unknown)[0]}",
            "unknown key (known: base_config, elements, axes)",
        )
    base = sweep.get("base_config")
    if base is None:
        base_path = default_config_path()
    elif isinstance(base, str):
        base_path = (p.parent / base).resolve()
    else:
        raise ConfigError(str(p), "sweep.base_config", f"must be a path string, got {base!r}")
    elements = sweep.get("elements", 16)
    if (
        isinstance(elements, bool)
        or not isinstance(elements, int)
        or not 1 <= elements <= MAX_SWEEP_ELEMENTS
    ):
        raise ConfigError(
            str(p),
            "sweep.elements",
            f"must be an integer in [1, {MAX_SWEEP_ELEMENTS}], got {elements!r}",
        )
    axes = sweep.get("axes")
    if not isinstance(axes, dict) or not axes:
        raise ConfigError(
            str(p), "sweep.axes", "must be a table of at least one 'section.key' = [values]"
        )
    points = math.prod(len(v) if isinstance(v, list) else 1 for v in axes.values())
    if points > MAX_SWEEP_POINTS:
        raise ConfigError(
            str(p),
            "sweep.axes",
            f"the grid has {points:.4g} points, more than the {MAX_SWEEP_POINTS} one sweep may "
            "have; split it into several sweeps",
        )
    base_doc = read_toml(base_path)
    parsed: list[tuple[str, tuple[Any, ...]]] = []
    for key, values in axes.items():
        if key.count(".") != 1:
            raise ConfigError(str(p), f"sweep.axes.{key}", "must be written 'section.key'")
        if not isinstance(values, list) or not values:
            raise ConfigError(str(p), f"sweep.axes.{key}", "must be a non-empty array of values")
        section, name = key.split(".")
        if name not in base_doc.get(section, {}):
            raise ConfigError(
                str(p), f"sweep.axes.{key}", f"is not a key of the base config {base_path}"
            )
        parsed.append((key, tuple(values)))
    return SweepSpec(str(p), base_path, elements, tuple(parsed))


def point_document(
    base_doc: Mapping[str, Any], values: Mapping[str, Any], elements: int
) -> dict[str, Any]:
    """The point's whole effective config: the base config with the sweep's ``elements``
    as its ``[table] elements`` and the point's values set (a number for an array key
    fills it; an axis over ``table.elements`` wins)."""
    doc = copy.deepcopy(dict(base_doc))
    doc.setdefault("table", {})["elements"] = elements
    for key, value in values.items():
        section, name = key.split(".")
        old = doc[section][name]
        doc[section][name] = (
            [value] * len(old) if isinstance(old, list) and not isinstance(value, list) else value
        )
    return doc


@dataclass(frozen=True)
class PointJob:
    """Everything a worker needs to make one table (paths are absolute)."""

    index: int
    config_path: str
    table_path: str


def build_point(job: PointJob) -> dict[str, Any]:
    """Validate one point's config and write its table (every setting, ``elements``
    included, from that file); returns its fidelity figures."""
    # the ball model loads only where tables are made
    from gms_comp.tables.reduction import reduce_to_gms
    from sim.scenarios import load_plant

    cfg = load_ball_config(job.config_path)
    ball_sets = load_plant(job.config_path).ball_set_count
    table = reduce_to_gms(cfg, ball_sets=ball_sets)
    write_table(job.table_path, table)
    return _fidelity_row(table)


def _done_fidelity(table_path: Path, sha256: str) -> dict[str, Any] | str | None:
    """Fidelity of an existing table made from the same config bytes; a note when a
    table is there but from another config; None when there is none."""
    if not table_path.exists():
        return None
    try:
        table = read_table(table_path)
    except TableError:
        return "the table there was unreadable: recomputed"
    if table.source_sha256 != sha256:
        return "the point's config changed since its table was made: recomputed"
    return _fidelity_row(table)


def _fidelity_row(table: GmsTable) -> dict[str, Any]:
    return {"rms_rel": table.fidelity.rms_rel, "max_rel": table.fidelity.max_rel}


def run_sweep(
    spec: SweepSpec,
    out_dir: str | Path,
    *,
    client: Any | None = None,
    progress: bool | None = None,
) -> dict[str, Any]:
    """Make (or complete) the family of ``spec`` in ``out_dir``; returns the manifest."""
    out = Path(out_dir)
    points_dir = out / "points"
    points_dir.mkdir(parents=True, exist_ok=True)
    base_doc = read_toml(spec.base_config)
    rows: list[dict[str, Any]] = []
    jobs: list[PointJob] = []
    for index, values in enumerate(spec.grid()):
        cfg_path = points_dir / f"{index:04d}.toml"
        table_path = points_dir / f"{index:04d}.json"
        doc = point_document(base_doc, values, spec.elements)
        write_bytes(cfg_path, tomli_w.dumps(doc).encode())
        sha = config_hash(cfg_path)
        row: dict[str, Any] = {
            "index": index,
            "values": values,
            "config": str(cfg_path.relative_to(out)),
            "config_sha256": sha,
            "table": str(table_path.relative_to(out)),
            "status": "pending",
        }
        done = _done_fidelity(table_path, sha)
        if isinstance(done, dict):
            row.update(status="ok", fidelity=done, resumed=True)
        else:
            if done is not None:
                row["note"] = done
            jobs.append(PointJob(index, str(cfg_path.resolve()), str(table_path.resolve())))
        rows.append(row)
    manifest = {
        "format": FAMILY_FORMAT,
        "version": FAMILY_VERSION,
        "gms_comp_version": __version__,
        "sweep_file": spec.path,
        "base_config": str(spec.base_config),
        "elements": spec.elements,
        "axes": {k: list(v) for k, v in spec.axes},
        "points": rows,
    }
    _write_manifest(out, manifest)
    # The manifest is rewritten every few seconds, not after every point (that is
    # quadratic in a 10 000-point catalogue); finished tables are never lost, since
    # resuming recognises them from their files.
    written = time.monotonic()
    result: JobResult[dict[str, Any]]
    try:
        for result in run_jobs(build_point, jobs, client=client, desc="sweep", progress=progress):
            job = jobs[result.index]
            row = rows[job.index]
            if result.ok:
                row.update(status="ok", fidelity=result.value)
            else:
                invalid = result.error.startswith(ConfigError.__name__)
                row.update(status="invalid" if invalid else "error", reason=result.error)
                row.pop("table")
            if time.monotonic() - written > MANIFEST_INTERVAL_S:
                _write_manifest(out, manifest)
                written = time.monotonic()
    finally:
        _write_manifest(out, manifest)
    return manifest


def _write_manifest(out: Path, manifest: Mapping[str, Any]) -> None:
    write_text(out / MANIFEST, json.dumps(manifest, indent=2) + "\n")


def read_manifest(family_dir: str | Path) -> dict[str, Any]:
    """Load a family's manifest, refusing files of another format or version."""
    path = Path(family_dir) / MANIFEST
    if not path.is_file():
        raise TableError(f"{path}: no manifest (is this a table family folder?)")
    text = read_text(path, max_bytes=4 * MAX_TABLE_BYTES, what="manifest", error=TableError)
    manifest = parse_json(text, str(path), error=TableError)
    if (
        not isinstance(manifest, dict)
        or manifest.get("format") != FAMILY_FORMAT
        or manifest.get("version") != FAMILY_VERSION
    ):
        raise TableError(f"{path}: not a {FAMILY_FORMAT} manifest of version {FAMILY_VERSION}")
    return dict(manifest)


@dataclass(frozen=True)
class TableFamily:
    """A swept family of tables, interpolated multilinearly between grid points.

    Elements are blended index by index (the reduction uses the same
    breakpoint pattern at every point), so the blend is exact at the grid
    points and linear in between. Axes whose values are not numbers can only
    be matched exactly.
    """

    path: str
    axes: tuple[tuple[str, tuple[Any, ...]], ...]
    tables: Mapping[tuple[int, ...], GmsTable]

    def table_at(self, values: Mapping[str, Any]) -> GmsTable:
        """The table for ``values`` (one per axis), interpolated inside the grid."""
        missing = [k for k, _ in self.axes if k not in values]
        if missing or len(values) != len(self.axes):
            known = ", ".join(k for k, _ in self.axes)
            raise TableError(f"{self.path}: give one value for each axis ({known})")
        per_axis = [_brackets(self.path, key, grid, values[key]) for key, grid in self.axes]
        corners: list[tuple[float, GmsTable]] = []
        for combo in itertools.product(*per_axis):
            weight = float(np.prod([w for _, w in combo]))
            if weight == 0.0:
                continue
            index = tuple(i for i, _ in combo)
            if index not in self.tables:
                raise TableError(f"{self.path}: grid point {index} has no valid table")
            corners.append((weight, self.tables[index]))
        laws = {t.params.limit_follows_level for _, t in corners}
        if len(laws) > 1:  # a law is not blended
            raise TableError(f"{self.path}: the grid points around {dict(values)} differ in law")
        return _blend(corners)


def _brackets(path: str, key: str, grid: tuple[Any, ...], value: Any) -> list[tuple[int, float]]:
    """Grid indices around ``value`` on one axis, with their linear weights."""
    if value in grid:
        return [(grid.index(value), 1.0)]
    numeric = all(isinstance(g, (int, float)) and not isinstance(g, bool) for g in grid)
    if not numeric or not isinstance(value, (int, float)):
        raise TableError(f"{path}: {key} = {value!r} is not a grid value ({list(grid)})")
    order = sorted(range(len(grid)), key=lambda i: grid[i])
    xs = [float(grid[i]) for i in order]
    if not xs[0] <= value <= xs[-1]:
        raise TableError(
            f"{path}: {key} = {value!r} is outside the family's range [{xs[0]}, {xs[-1]}]"
        )
    hi = next(j for j, x in enumerate(xs) if x >= value)
    lo = hi - 1
    t = (value - xs[lo]) / (xs[hi] - xs[lo])
    return [(order[lo], 1.0 - t), (order[hi], t)]


def _blend(corners: list[tuple[float, GmsTable]]) -> GmsTable:
    first = corners[0][1]
    if len(corners) == 1:
        return first
    blended: dict[str, Any] = {}
    for f in dataclasses.fields(first.params):
        vals = [getattr(t.params, f.name) for _, t in corners]
        if all(np.array_equal(v, vals[0]) for v in vals):
            blended[f.name] = vals[0]
        else:
            blended[f.name] = sum(
                w * np.asarray(v, dtype=float) for (w, _), v in zip(corners, vals, strict=True)
            )
            if np.ndim(blended[f.name]) == 0:
                blended[f.name] = float(blended[f.name])
    worst = max((t.fidelity for _, t in corners), key=lambda fid: fid.rms_rel)
    return dataclasses.replace(
        first, params=dataclasses.replace(first.params, **blended), fidelity=worst
    )


def load_family(family_dir: str | Path) -> TableFamily:
    """Load a family written by :func:`run_sweep` (points that failed are left out)."""
    root = Path(family_dir)
    manifest = read_manifest(root)
    axes = tuple((k, tuple(v)) for k, v in manifest["axes"].items())
    shape = [len(v) for _, v in axes]
    tables: dict[tuple[int, ...], GmsTable] = {}
    for row in manifest["points"]:
        if row.get("status") == "ok":
            index = tuple(int(i) for i in np.unravel_index(int(row["index"]), shape))
            tables[index] = read_table(root / row["table"])
    if not tables:
        raise TableError(f"{root / MANIFEST}: the family holds no valid table")
    return TableFamily(str(root), axes, tables)
