"""``gms-comp config``: every config section and key, its unit, default and range.

One list, :data:`SECTIONS`, names the dataclass behind each ``[section]``; the
sections live in the layer that uses them (physics, reduction, sim, runtime, CAN,
diagnosis), so the list lives here, at the top. From it come the complete default
TOML (``--defaults``), the reference docs/config.md (``--markdown``) and the check
of a whole config file (every section parsed as the commands parse it).

The defaults are those a command uses without a config: the packaged seed Table 1
(``[bearing]``, ``[stand]``, ``[model]``) and the dataclass defaults elsewhere.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import json
import math
import re
import sys
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from firmware_bridge.settings import CanConfig, load_can_config
from gms_comp.app.scaleout import ScaleoutConfig, load_scaleout
from gms_comp.arguments import input_file, output_file
from gms_comp.atomic import write_text
from gms_comp.config import default_config_path, is_section, parse_section, read_toml
from gms_comp.measured.diagnosis.run import DiagnosisConfig, load_diagnosis_config
from gms_comp.physics.config import BearingConfig, ModelConfig, StandConfig, load_ball_config
from gms_comp.runtime.observer import CompensatorConfig
from gms_comp.tables.reduction import TableConfig, check_request, load_table_config
from sim.controller import ControllerConfig
from sim.machine import MachineConfig, load_machine, machine_section
from sim.plant import PlantConfig
from sim.scenarios import ScenarioConfig, load_scenario

# Every [section] of a gms-comp config and the dataclass that reads it, in file order.
SECTIONS: dict[str, type[Any]] = {
    "bearing": BearingConfig,
    "stand": StandConfig,
    "model": ModelConfig,
    "table": TableConfig,
    "plant": PlantConfig,
    "controller": ControllerConfig,
    "scenario": ScenarioConfig,
    "compensator": CompensatorConfig,
    "can": CanConfig,
    "machine": MachineConfig,
    "diagnosis": DiagnosisConfig,
    "scaleout": ScaleoutConfig,
}

# Units from a key's name suffix (longest suffixes first); keys without one are plain numbers.
UNIT_SUFFIXES: tuple[tuple[str, str], ...] = (
    ("_N_per_A", "N/A"),
    ("_A_per_s", "A/s"),
    ("_N_per_m3", "N/m^3"),
    ("_bit_s", "bit/s"),
    ("_m_s", "m/s"),
    ("_per_s", "1/s"),
    ("_cycles", "cycles"),
    ("_steps", "encoder steps"),
    ("_Pa", "Pa"),
    ("_Hz", "Hz"),
    ("_kg", "kg"),
    ("_m", "m"),
    ("_N", "N"),
    ("_A", "A"),
    ("_s", "s"),
)

_MARKDOWN_COMMAND = "gms-comp config --markdown -o docs/config.md"


@dataclasses.dataclass(frozen=True)
class Key:
    """One key of a section: its value in a config, unit, default and accepted values.

    ``default`` is what a config file that leaves the key out gets (``required`` when
    there is none); ``packaged`` is the value of the packaged Table 1 config, which
    commands run without a config use.
    """

    section: str
    name: str
    value: Any
    unit: str
    default: Any
    required: bool
    packaged: Any
    accepted: str
    why: str = ""


def unit_of(name: str) -> str:
    """The unit a key's name carries (``force_N`` -> ``N``), ``""`` for a plain number."""
    for suffix, unit in UNIT_SUFFIXES:
        if name.endswith(suffix):
            return unit
    return ""


def accepted_values(cls: type[Any], f: dataclasses.Field[Any]) -> str:
    """What a key accepts, as the config check states it (``> 0``, ``in [0, 0.5)``, ...)."""
    hint = typing.get_type_hints(cls)[f.name]
    if typing.get_origin(hint) is typing.Literal:
        return "one of " + ", ".join(_toml(v) for v in typing.get_args(hint))
    if hint is bool:
        return "true or false"
    check = f.metadata.get("check")
    kind = {int: "integer", float: "number", str: "text"}.get(hint, "")
    if typing.get_origin(hint) is tuple:
        kind = "array of numbers"
    if check is None:
        return kind
    # A non-finite value fails every range check, whose reason states the range.
    reason = check(math.nan)
    text = reason.removeprefix("must be ") if reason else ""
    return f"{kind}, {text}" if text else kind


def check(path: Path) -> None:
    """Refuse ``path`` wherever a command would: every command's own loader runs on it
    (the ball model's with its contact check, the table's request, the scenario's with
    its durations, cycles, trajectory and table file, the CAN link's, the diagnosis's,
    the scale-out's, the simulated machine's), so ``config`` says valid exactly when
    none of them refuses."""
    ball = load_ball_config(path)
    table = load_table_config(path)
    check_request(ball, table.elements, table)
    load_scenario(path)
    load_can_config(path)
    load_diagnosis_config(path)
    load_scaleout(read_toml(path), path)
    load_machine(path)  # [machine]'s effect parameters, beyond its own keys


def all_sections() -> list[tuple[str, type[Any]]]:
    """Every section and sub-section (``[diagnosis.selection]``) with its dataclass, in
    file order."""
    out: list[tuple[str, type[Any]]] = []

    def add(name: str, cls: type[Any]) -> None:
        out.append((name, cls))
        hints = typing.get_type_hints(cls)
        for f in dataclasses.fields(cls):
            if is_section(hints[f.name]):
                add(f"{name}.{f.name}", hints[f.name])

    for section, cls in SECTIONS.items():
        add(section, cls)
    return out


def _within(obj: Any, dotted: str) -> Any:
    """The sub-section object at ``dotted`` (``a.b.c``: ``obj.b.c``) below ``obj``."""
    for name in dotted.split(".")[1:]:
        obj = getattr(obj, name)
    return obj


def keys(path: str | Path | None = None) -> list[Key]:
    """Every key of every section, with its value in ``path`` (default: the packaged config).

    Each section is parsed as the commands parse it and the file is checked as every
    command checks it (:func:`check`), so a bad file raises the same
    :class:`~gms_comp.errors.ConfigError`.
    """
    packaged = default_config_path()
    p = Path(path) if path is not None else packaged
    doc = read_toml(p)
    packaged_doc = doc if p == packaged else read_toml(packaged)
    found = []
    parsed = {s: parse_section(machine_section(doc), p, s, cls) for s, cls in SECTIONS.items()}
    packaged_parsed = {
        s: parse_section(machine_section(packaged_doc), packaged, s, c) for s, c in SECTIONS.items()
    }
    check(p)
    for section, cls in all_sections():
        top = section.split(".")[0]
        values = _within(parsed[top], section)
        packaged_values = _within(packaged_parsed[top], section)
        hints = typing.get_type_hints(cls)
        defaults = cls() if _all_default(cls) else None
        for f in dataclasses.fields(cls):
            if is_section(hints[f.name]):
                continue
            required = f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
            found.append(
                Key(
                    section=section,
                    name=f.name,
                    value=getattr(values, f.name),
                    unit=unit_of(f.name),
                    default=None if required else getattr(defaults or cls, f.name, None),
                    required=required,
                    packaged=getattr(packaged_values, f.name),
                    accepted=accepted_values(cls, f),
                    why=f.metadata.get("why", ""),
                )
            )
    return found


def _all_default(cls: type[Any]) -> bool:
    return all(
        f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING
        for f in dataclasses.fields(cls)
    )


def _toml(value: Any) -> str:
    """A config value as TOML (numbers, booleans, strings, arrays of numbers)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return repr(value)
    if isinstance(value, float):
        if value != 0 and not 1e-4 <= abs(value) < 1e6:  # 2.1e+11, not 210000000000.0
            mantissa, exponent = f"{value:.12e}".split("e")
            return f"{mantissa.rstrip('0').rstrip('.')}e{exponent}"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, tuple):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    raise TypeError(f"no TOML form for {value!r}")  # a programming error


def _summary_line(cls: type[Any]) -> str:
    """The first docstring line of a section's dataclass, without "The [x] section"."""
    line = (cls.__doc__ or "").strip().splitlines()[0]
    line = re.sub(r"^The ``\[[\w.]+\]`` section[:.]?\s*", "", line).replace("``", "`")
    return line[:1].upper() + line[1:]


def to_toml(entries: list[Key], source: str) -> str:
    """A complete config file: every section and key, each with its unit and range."""
    lines = [
        f"# Complete gms-comp config ({source}): every section and key.",
        "# Reference: docs/config.md (gms-comp config --markdown). SI units throughout.",
    ]
    for section, cls in all_sections():
        about = _summary_line(cls)
        lines += ["", f"[{section}]" + (f"  # {about}" if about else "")]
        for k in (e for e in entries if e.section == section):
            note = "; ".join(x for x in (k.unit, k.accepted) if x)
            if k.value == ():  # TOML has no empty-array key the loader accepts: leave it out
                lines.append(f"# {k.name} = [{_unit_example(k)}]  # {note}; default: none")
            else:
                lines.append(f"{k.name} = {_toml(k.value)}  # {note}")
    return "\n".join(lines) + "\n"


def _unit_example(k: Key) -> str:
    return "..." if not k.unit else f"... in {k.unit}"


def to_markdown(entries: list[Key]) -> str:
    """The config reference: one table per section with unit, default and range."""
    lines = [
        "# Config reference",
        "",
        f"Generated by `{_MARKDOWN_COMMAND}` from the config dataclasses; "
        "tests/test_config_docs.py fails when it is out of date.",
        "",
        "A config file is TOML with the sections below, every one optional except "
        "`[bearing]` and `[stand]` (keys marked *required*). Values are SI; a key's "
        "name ends in its unit (`ball_radius_m`, `servo_rate_Hz`). Unknown sections "
        "or keys and values out of range are refused with the file, key and reason. "
        "Without a config, commands use the packaged seed Table 1 (the defaults below).",
        "",
        "`gms-comp config --defaults` prints a complete config with every default; "
        "`gms-comp config FILE` checks a file the way the commands read it.",
    ]
    for section, cls in all_sections():
        mine = [e for e in entries if e.section == section]
        explained = any(k.why for k in mine)
        lines += [
            "",
            f"## [{section}]",
            "",
            f"{_summary_line(cls)} (read by `{cls.__module__}.{cls.__name__}`)".lstrip(),
            "",
            "| key | unit | default | accepted |" + (" why |" if explained else ""),
            "| --- | --- | --- | --- |" + (" --- |" if explained else ""),
        ]
        for k in mine:
            default = "*required*" if k.required else _shown(k.default)
            if k.required or k.packaged != k.default:
                default += f" (Table 1: {_shown(k.packaged)})"
            why = f" {k.why or '-'} |" if explained else ""
            lines.append(f"| `{k.name}` | {k.unit or '-'} | {default} | {k.accepted or '-'} |{why}")
        together = _cross_key_rule(cls)
        if together:
            lines += ["", f"Checked together: {together}"]
    return "\n".join(lines) + "\n"


def _cross_key_rule(cls: type[Any]) -> str:
    """The rule a section's ``problems()`` checks across keys, from its docstring."""
    method = getattr(cls, "problems", None)
    doc = inspect.getdoc(method) if method is not None else None
    return " ".join(doc.split("\n\n")[0].split()) if doc else ""


def _shown(value: Any) -> str:
    return "none" if value == () else f"`{_toml(value)}`"


def to_json(entries: list[Key], source: str) -> dict[str, Any]:
    """The config's values by section (SI units), JSON-ready."""
    sections: dict[str, Any] = {name: {} for name in SECTIONS}
    for k in entries:
        table: dict[str, Any] = sections
        for name in k.section.split("."):
            table = table.setdefault(name, {})
        table[k.name] = list(k.value) if isinstance(k.value, tuple) else k.value
    return {"config": source, "sections": sections}


def _set_in_file(path: Path, entries: list[Key]) -> int:
    doc: Mapping[str, Any] = read_toml(path)
    count = 0
    for k in entries:
        table: Any = doc
        for name in k.section.split("."):
            table = table.get(name, {}) if isinstance(table, Mapping) else {}
        count += int(isinstance(table, Mapping) and k.name in table)
    return count


def register(subparsers: Any) -> None:
    """Add the ``config`` subcommand."""
    parser = subparsers.add_parser(
        "config",
        help="check a config; print the complete default config or the config reference",
        description=(
            "Without options: check CONFIG (default: the packaged seed Table 1) the way the "
            "commands read it, every section and key. --defaults prints a complete config "
            "with every key at its default (TOML, unit and range in a comment on each line); "
            "--markdown prints the reference of every section and key (docs/config.md)."
        ),
    )
    parser.add_argument(
        "config", nargs="?", type=input_file, help="config TOML to check (default: Table 1)"
    )
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument(
        "--defaults", action="store_true", help="print the complete default config (TOML)"
    )
    mode.add_argument(
        "--markdown", action="store_true", help="print the config reference (Markdown)"
    )
    parser.add_argument(
        "-o",
        "--output",
        type=output_file,
        metavar="FILE",
        help="write the --defaults or --markdown text to FILE instead of stdout",
    )
    parser.add_argument(
        "--json", action="store_true", help="print the config's values as JSON on stdout only"
    )
    parser.set_defaults(func=run, parser=parser)


def run(args: argparse.Namespace) -> int:
    """Check a config or print/write the default config or the reference."""
    if args.defaults and args.config is not None:
        args.parser.error("--defaults prints the packaged defaults: give no CONFIG with it")
    if args.output is not None and not (args.defaults or args.markdown):
        args.parser.error("-o/--output writes --defaults or --markdown: give one of them")
    entries = keys(args.config)
    source = str(args.config) if args.config is not None else "defaults: seed Table 1"
    text = None
    if args.defaults:
        text = to_toml(entries, source)
    elif args.markdown:
        text = to_markdown(entries)
    if args.json:
        print(json.dumps(to_json(entries, source), indent=2))
    elif text is not None and args.output is None:
        sys.stdout.write(text)
    elif text is None:
        where = args.config if args.config is not None else default_config_path()
        given = _set_in_file(Path(where), entries)
        print(
            f"{where}: valid; {len(SECTIONS)} sections, {len(entries)} keys "
            f"({given} set in the file, the others at their defaults)"
        )
    if args.output is not None and text is not None:
        write_text(args.output, text)
        print(f"wrote {args.output}", file=sys.stderr if args.json else sys.stdout)
    return 0
