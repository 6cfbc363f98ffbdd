"""A diagnosis report written as one set: its plots, page and table, and a manifest.

The report folder is written by :func:`gms_comp.atomic.replaced_folder`: the old report
is moved aside before anything of the new run is written (a table named with ``--table``
included), the new one is made in a hidden folder and renamed into place at the end, its
``manifest.json`` written last. The manifest names every input of the run (path and
SHA-256) and every file of the set (with its SHA-256, the table outside the folder
included); the page and each plot name the inputs too, and the table names its trace
(``source``). A run killed at any moment leaves the old set (moved aside, hidden), or no
report, or the new complete one: never a new table beside an old report that looks
complete.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from gms_comp import __version__
from gms_comp.atomic import SET_MANIFEST, atomic_path, replaced_folder, write_text
from gms_comp.measured.diagnosis.result import Diagnosis
from gms_comp.tables.table import GmsTable, write_table

REPORT_FORMAT = "gms-comp-report"
REPORT_VERSION = 1
#: The table's name inside a report folder when no ``--table`` is given.
TABLE_NAME = "extended.table.json"


def input_record(inputs: Mapping[str, str | os.PathLike[str] | None]) -> dict[str, Any]:
    """``{name: {"path": absolute path, "sha256": ...}}`` for each input given."""
    return {
        name: {"path": os.path.abspath(path), "sha256": _sha256(Path(path))}
        for name, path in inputs.items()
        if path
    }


def write_report_set(
    diagnosis: Diagnosis,
    folder: str | Path,
    inputs: Mapping[str, Any],
    table: GmsTable | None = None,
    table_path: str | Path | None = None,
    doc: Mapping[str, Any] | None = None,
) -> list[Path]:
    """Write the report of ``diagnosis`` into ``folder`` as one set; return the files.

    ``inputs`` is :func:`input_record`'s; ``table`` (the extended model) goes to
    ``table_path`` if given, else into the folder as :data:`TABLE_NAME`; ``doc`` is the
    diagnosis JSON the page shows (intervals, detection limits, caveats, cross-test).
    """
    from gms_comp.app.report import write_report  # matplotlib only when asked for

    final = Path(folder)
    named = {name: f"{v['path']} (sha256 {v['sha256'][:12]})" for name, v in inputs.items()}
    outside = Path(table_path) if table is not None and table_path is not None else None
    with replaced_folder(final) as tmp, contextlib.ExitStack() as stack:
        # the table named on the command line replaces the old one only when the whole set
        # is written (the stack closes just before the folder is renamed into place)
        staged = stack.enter_context(atomic_path(outside)) if outside is not None else None
        files: dict[str, Path] = {}  # the set's name of each file -> where it is written
        if table is not None:
            target = staged if staged is not None else tmp / TABLE_NAME
            write_table(target, table)
            files[os.path.abspath(outside) if outside is not None else TABLE_NAME] = target
        page = {**(doc if doc is not None else diagnosis.to_json()), "inputs": named}
        files.update((p.name, p) for p in write_report(diagnosis, page, tmp))
        manifest = {
            "format": REPORT_FORMAT,
            "version": REPORT_VERSION,
            "gms_comp_version": __version__,
            "inputs": dict(inputs),
            "files": {name: _sha256(path) for name, path in files.items()},
        }
        write_text(tmp / SET_MANIFEST, json.dumps(manifest, indent=2) + "\n")
    return [Path(n) if os.path.isabs(n) else final / n for n in files] + [final / SET_MANIFEST]


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
