"""docs/limits.md lists every bound gms-comp enforces on its input; this test keeps it true.

The document is generated from the code: the range metadata of every config
section's fields, the declared parameters of each catalogue effect, and the caps
(``MAX_*``/``MIN_*`` constants and the ``*_SUFFIXES`` of output formats, documented with
``#:`` comments) of the modules that check untrusted input. When a bound changes, rewrite it:

    python tests/test_limits_doc.py
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import re
import sys
import typing
from pathlib import Path
from typing import Any

from gms_comp.config import is_section

DOC = Path(__file__).resolve().parents[1] / "docs" / "limits.md"

SECTIONS = (
    ("bearing", "gms_comp.physics.config", "BearingConfig"),
    ("stand", "gms_comp.physics.config", "StandConfig"),
    ("model", "gms_comp.physics.config", "ModelConfig"),
    ("table", "gms_comp.tables.reduction", "TableConfig"),
    ("compensator", "gms_comp.runtime.observer", "CompensatorConfig"),
    ("plant", "sim.plant", "PlantConfig"),
    ("controller", "sim.controller", "ControllerConfig"),
    ("scenario", "sim.scenarios", "ScenarioConfig"),
    ("can", "firmware_bridge.settings", "CanConfig"),
    ("diagnosis", "gms_comp.measured.diagnosis.run", "DiagnosisConfig"),
    ("scaleout", "gms_comp.app.scaleout", "ScaleoutConfig"),
    ("machine", "sim.machine", "MachineConfig"),
)
CAP_MODULES = (
    "gms_comp.validation",
    "gms_comp.arguments",
    "gms_comp.physics.config",
    "gms_comp.physics.contact",
    "gms_comp.tables.table",
    "gms_comp.measured.trace_csv",
    "gms_comp.measured.trace_map",
    "gms_comp.measured.trace_clock",
    "gms_comp.measured.trace_units",
    "gms_comp.app.sweep",
    "gms_comp.app.replay",
    "sim.scenarios",
    "firmware_bridge.frame_log",
)
_CAP = re.compile(r"((?:^#:.*\n)+)^((?:MAX|MIN)_[A-Z0-9_]+|[A-Z_]+_SUFFIXES)\s*=", re.MULTILINE)


def _number(value: float | tuple[str, ...]) -> str:
    if isinstance(value, tuple):
        return ", ".join(f"`{v}`" for v in value)
    if isinstance(value, int):
        return f"{value:,}".replace(",", " ")
    if math.isinf(value):
        return "inf"
    return f"{value:g}"


def _range(f: dataclasses.Field[Any], hint: Any) -> str:
    if typing.get_origin(hint) is typing.Literal:
        return "one of " + ", ".join(f"`{c}`" for c in typing.get_args(hint))
    bounds = f.metadata.get("range")
    if bounds is None:
        return "any" if hint in (str, bool) else "checked in code"
    lo, hi, lower, upper = bounds
    text = f"{lower}{_number(lo)}, {_number(hi)}{upper}"
    if f.metadata.get("max_items"):
        text += f", at most {f.metadata['max_items']} entries"
    return text


def _default(f: dataclasses.Field[Any]) -> str:
    if f.default is not dataclasses.MISSING:
        return f"`{f.default!r}`"
    if f.default_factory is not dataclasses.MISSING:
        return f"`{f.default_factory()!r}`"
    return "required"


def _rows(section: str, cls: type[Any]) -> list[str]:
    """One row per key of ``cls``, a sub-section's (``[section.sub]``) after it in turn."""
    hints = typing.get_type_hints(cls)
    rows = []
    for f in dataclasses.fields(cls):
        if is_section(hints[f.name]):
            rows += _rows(f"{section}.{f.name}", hints[f.name])
            continue
        kind = getattr(hints[f.name], "__name__", str(hints[f.name]))
        kind = str(hints[f.name]) if "[" in str(hints[f.name]) else kind
        kind = kind.replace("typing.", "")
        rows.append(
            f"| `{section}.{f.name}` | {kind} | {_default(f)} | {_range(f, hints[f.name])} |"
        )
    return rows


def render() -> str:
    """The whole of docs/limits.md, from the code."""
    out = [
        "# Limits: every bound on gms-comp's input",
        "",
        "Generated from the code by `python tests/test_limits_doc.py`; a test fails when the",
        "code and this page differ. A value outside its range, a file or count over its cap",
        "is refused before any work, with one line naming the file, the key or row and the",
        "reason, and exit code 2. Ranges are inclusive unless the bracket is round.",
        "",
        "## Config keys",
        "",
        "| key | type | default | allowed |",
        "|---|---|---|---|",
    ]
    for section, module, name in SECTIONS:
        out += _rows(section, getattr(importlib.import_module(module), name))
    out += [
        "",
        "## Table extensions (catalogue effects)",
        "",
        "A table's extensions are read with each effect's declared parameters and ranges",
        "(`replay --model`, the observer).",
        "",
        "| parameter | default | allowed |",
        "|---|---|---|",
    ]
    from gms_comp.runtime.effects import CATALOGUE

    for effect, cls in CATALOGUE.items():
        hints = typing.get_type_hints(cls)
        for f in dataclasses.fields(cls):
            out.append(f"| `{effect}.{f.name}` | {_default(f)} | {_range(f, hints[f.name])} |")
    out += [
        "",
        "## Caps on files, counts and models",
        "",
        "| cap | value | what |",
        "|---|---|---|",
    ]
    for module in CAP_MODULES:
        mod = importlib.import_module(module)
        source = Path(str(mod.__file__)).read_text(encoding="utf-8")
        for comment, const in _CAP.findall(source):
            what = " ".join(line.removeprefix("#:").strip() for line in comment.splitlines())
            out.append(f"| `{module}.{const}` | {_number(getattr(mod, const))} | {what} |")
    return "\n".join(out) + "\n"


def test_limits_doc_matches_the_code() -> None:
    assert DOC.is_file(), "docs/limits.md is missing: run python tests/test_limits_doc.py"
    assert DOC.read_text(encoding="utf-8") == render(), (
        "docs/limits.md is out of date: run python tests/test_limits_doc.py"
    )


def test_every_known_section_is_listed() -> None:
    from gms_comp.config import KNOWN_SECTIONS

    assert {s for s, _, _ in SECTIONS} == set(KNOWN_SECTIONS)


if __name__ == "__main__":
    sys.path.insert(0, str(DOC.parents[1]))
    DOC.write_text(render(), encoding="utf-8")
    print(f"wrote {DOC}")
