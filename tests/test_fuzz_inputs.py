"""Fuzzing the command line: every bad input is refused in one line, exit 2, in bounded
time and memory.

Each case is a real command line (``python -m gms_comp ...`` in a child process under
a 3 GB address-space cap, see tests/cli_runner.py) on a file or value built to be bad,
grouped in the classes of the reliability audit (issue 13). An outcome is one of

- ``refused``: exit 2, exactly one error line on stderr, no traceback;
- ``traceback``, ``accepted`` (exit 0/1 on bad input: a silent acceptance), ``hang``
  (over the time bound), ``multi-line`` or ``crash`` (killed, e.g. by the memory cap).

The slow part runs every case through a fresh interpreter
(``subprocess``, no fork) and adds random mutations of the good files.
"""

from __future__ import annotations

import json
import os
import random
import struct
import subprocess
import sys
import zlib
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import scipy.io

from gms_comp.config import default_config_path

ROOT = Path(__file__).resolve().parents[1]
RUNNER = Path(__file__).with_name("cli_runner.py")
GOOD_CONFIG = default_config_path().read_text()
TIME_BOUND_S = 45.0


@dataclass(frozen=True)
class Case:
    """One bad command line: its audit class, the arguments and what the line must name."""

    id: str
    cls: str
    argv: tuple[str, ...]
    names: tuple[str, ...] = ()  # substrings the error line must hold (file, key, reason)
    files: dict[str, Callable[[Path], object]] = field(default_factory=dict, compare=False)


# --- building bad files -------------------------------------------------------------------


def _edit(key: str, value: str, text: str = GOOD_CONFIG) -> str:
    lines = []
    for line in text.splitlines():
        if line.split("=")[0].strip() == key:
            line = f"{key} = {value}"
        lines.append(line)
    return "\n".join(lines) + "\n"


def _text(content: str) -> Callable[[Path], object]:
    return lambda p: p.write_text(content, encoding="utf-8")


def _bytes(content: bytes) -> Callable[[Path], object]:
    return lambda p: p.write_bytes(content)


def _good_trace_rows(n: int = 2000) -> list[list[float]]:
    t = np.arange(n) * 1e-3
    x = 5e-3 * np.sin(2 * np.pi * 0.5 * t)
    v = np.gradient(x, t)
    f = 3.0 * np.tanh(v / 1e-3) + 0.5 * v
    return [list(r) for r in zip(t, x, f, strict=True)]


def _csv(rows: list[list[float]], header: str = "time_s,position_m,force_N") -> str:
    return header + "\n" + "\n".join(",".join(f"{v:.12g}" for v in r) for r in rows) + "\n"


def _trace_with(column: int, fn: Callable[[float, int], float], header: str = "") -> str:
    rows = _good_trace_rows()
    for i, r in enumerate(rows):
        r[column] = fn(r[column], i)
    return _csv(rows, header or "time_s,position_m,force_N")


def _table_doc(good: Path) -> dict[str, Any]:
    doc: dict[str, Any] = json.loads(good.read_text())
    return doc


def _table_edit(edit: Callable[[dict[str, Any]], None]) -> Callable[[Path], None]:
    def build(p: Path) -> None:
        doc = _table_doc(p.parent / "good.table.json")
        edit(doc)
        p.write_text(json.dumps(doc))

    return build


def _million_elements(p: Path) -> None:
    doc = _table_doc(p.parent / "good.table.json")
    n = 1_000_000
    doc.update(elements=n, stiffness_N_per_m=[1.0] * n, limit_N=[1.0] * n)
    p.write_text(json.dumps(doc))


def _emps_matrix(p: Path) -> None:
    t = np.arange(500) * 1e-3
    both = np.column_stack([t, 2 * t])
    scipy.io.savemat(p, {"t": t[:, None], "qm": both, "vir": both, "gtau": np.array([[1.0]])})


def write_expanding_mat(p: Path, n: int = 150_000_000, name: bytes = b"qm") -> None:
    """A MATLAB v5 file of a few MB whose compressed variable ``name`` expands to n
    doubles (1.2 GB for the default): the audit's "777 kB that expands to 1.2 GB"."""
    padded = name + b"\0" * (-len(name) % 8)
    nbytes = 8 * n
    body = (
        struct.pack("<IIII", 6, 8, 6, 0)  # array flags: class double
        + struct.pack("<IIii", 5, 8, n, 1)  # dimensions n x 1
        + struct.pack("<II", 1, len(name))
        + padded
        + struct.pack("<II", 9, nbytes)  # the real part follows
    )
    comp = zlib.compressobj(1)
    parts = [comp.compress(struct.pack("<II", 14, len(body) + nbytes) + body)]
    zeros = bytes(1 << 24)
    left = nbytes
    while left:
        k = min(left, len(zeros))
        parts.append(comp.compress(zeros[:k]))
        left -= k
    parts.append(comp.flush())
    payload = b"".join(parts)
    header = b"MATLAB 5.0 MAT-file, gms-comp fuzz".ljust(116) + bytes(8) + b"\x00\x01IM"
    p.write_bytes(header + struct.pack("<II", 15, len(payload)) + payload)


def _report_with_trace(p: Path) -> None:
    """A report folder gms-comp wrote (its manifest) into which a trace was copied."""
    p.mkdir()
    (p / "manifest.json").write_text("{}")
    (p / "t.csv").write_text(_csv(_good_trace_rows()))


def _sweep(axes: str) -> str:
    head = f'[sweep]\nbase_config = "{default_config_path()}"\nelements = 2\n'
    return head + f"[sweep.axes]\n{axes}\n"


def _deep(n: int = 5000) -> str:
    return "[" * n + "]" * n


LATIN1 = "# Kugellager für die Achse\n".encode("latin-1")
CAN = "\n[can]\n"
SIM = "\n[controller]\n"

# --- the cases ---------------------------------------------------------------------------

CASES: list[Case] = [
    # extreme but finite values (each config key's range: tests/test_schema_configs.py draws
    # values below, above and beyond it for every key; these go through the real CLI)
    Case(
        "contact_wider_than_ball",
        "extreme",
        ("table", "c.toml", "-o", "t.json"),
        ("stand.ball_loads_N", "contact ellipse"),
        files={
            "c.toml": _text(
                _edit(
                    "youngs_modulus_raceway_Pa",
                    "1e8",
                    _edit("youngs_modulus_ball_Pa", "1e8", _edit("ball_loads_N", "[2000.0]")),
                )
            )
        },
    ),
    Case(
        "rated_current_1e-300",
        "extreme",
        ("stream", "c.toml", "--duration", "0.2"),
        ("can.rated_current_A",),
        files={"c.toml": _text(GOOD_CONFIG + CAN + "rated_current_A = 1e-300\n")},
    ),
    Case(
        "cycle_period_1e-9",
        "extreme",
        ("stream", "c.toml", "--duration", "0.2"),
        ("can.cycle_period_s",),
        files={"c.toml": _text(GOOD_CONFIG + CAN + "cycle_period_s = 1e-9\n")},
    ),
    Case(
        "table_stiffness_1e308",
        "extreme",
        ("diagnose", "good.csv", "--table-in", "b.json"),
        ("b.json", "stiffness_N_per_m[0]"),
        files={"b.json": _table_edit(lambda d: d["stiffness_N_per_m"].__setitem__(0, 1e308))},
    ),
    Case(
        "sweep_elements_1e9",
        "extreme",
        ("sweep", "s.toml", "--serial", "-o", "fam"),
        ("s.toml", "sweep.elements"),
        files={
            "s.toml": _text(
                _sweep('"stand.ball_loads_N" = [50.0]').replace(
                    "elements = 2", "elements = 1000000000"
                )
            )
        },
    ),
    # resource bounds
    Case(
        "profile_rate_1e9",
        "resources",
        ("profile", "p.csv", "--sample-rate-hz", "1e9"),
        ("sample-rate",),
    ),
    Case(
        "table_elements_100000",
        "resources",
        ("table", "-o", "t.json", "--elements", "100000"),
        ("elements",),
    ),
    Case(
        "ball_loads_200000",
        "resources",
        ("model", "c.toml"),
        ("stand.ball_loads_N", "200000"),
        files={"c.toml": _text(_edit("ball_loads_N", "[" + ", ".join(["50.0"] * 200_000) + "]"))},
    ),
    Case(
        "family_loads_200",
        "resources",
        ("table", "-o", "t.json", "--family-loads", ",".join(["50"] * 200)),
        ("200 loads",),
    ),
    Case(
        "table_million_elements",
        "resources",
        ("diagnose", "good.csv", "--table-in", "m.json"),
        ("m.json", "elements", "1000000"),
        files={"m.json": _million_elements},
    ),
    Case(
        "mat_expands_to_1_2GB",
        "resources",
        (
            "diagnose",
            "big.mat",
            "--map",
            "time_s=qm",
            "--map",
            "position_m=qm",
            "--map",
            "force_N=qm",
        ),
        ("big.mat", "variable qm", "declares"),
        files={"big.mat": write_expanding_mat},
    ),
    Case(
        "sweep_grid_8e9",
        "resources",
        ("sweep", "s.toml", "--serial", "-o", "fam"),
        ("s.toml", "sweep.axes", "8e+09 points"),
        files={
            "s.toml": _text(
                _sweep(
                    "\n".join(
                        f'"{k}" = [{", ".join(str(v + i * 1e-7) for i in range(2000))}]'
                        for k, v in (
                            ("bearing.friction_coefficient", 1e-3),
                            ("stand.carriage_velocity_m_s", 1e-2),
                            ("stand.rolling_distance_per_travel", 0.4),
                        )
                    )
                )
            )
        },
    ),
    Case(
        "sweep_workers_-1",
        "resources",
        ("sweep", "s.toml", "--workers", "-1"),
        ("--workers",),
        files={"s.toml": _text(_sweep('"stand.ball_loads_N" = [50.0]'))},
    ),
    Case(
        "stream_duration_1e7",
        "resources",
        ("stream", "--duration", "1e7"),
        ("duration",),
    ),
    Case(
        "csv_100000_columns",
        "resources",
        ("diagnose", "w.csv"),
        ("w.csv", "columns"),
        files={"w.csv": _text(",".join(f"c{i}" for i in range(100_000)) + "\n")},
    ),
    # non-UTF-8
    Case(
        "config_latin1",
        "non-utf8",
        ("model", "c.toml"),
        ("c.toml", "not UTF-8"),
        files={"c.toml": _bytes(GOOD_CONFIG.encode() + LATIN1)},
    ),
    Case(
        "table_latin1",
        "non-utf8",
        ("diagnose", "good.csv", "--table-in", "b.json"),
        ("b.json", "not UTF-8"),
        files={
            "b.json": lambda p: p.write_bytes(
                (p.parent / "good.table.json")
                .read_bytes()
                .replace(b'"source"', '"sourcé"'.encode("latin-1"))
            )
        },
    ),
    Case(
        "sweep_latin1",
        "non-utf8",
        ("sweep", "s.toml", "--serial"),
        ("s.toml", "not UTF-8"),
        files={"s.toml": _bytes(LATIN1 + _sweep('"stand.ball_loads_N" = [50.0]').encode())},
    ),
    Case(
        "trace_latin1",
        "non-utf8",
        ("diagnose", "l.csv"),
        ("l.csv", "not a text file"),
        files={
            "l.csv": _bytes(b"time_s,position_m,force_N,note\n" + "0,0,0,für\n".encode("latin-1"))
        },
    ),
    Case(
        "config_nul",
        "non-utf8",
        ("model", "c.toml"),
        ("c.toml", "NUL"),
        files={"c.toml": _bytes(b"\x00\x01\x02binary")},
    ),
    # deep nesting
    Case(
        "config_deep_array",
        "nesting",
        ("model", "c.toml"),
        ("c.toml", "nested"),
        files={"c.toml": _text(GOOD_CONFIG + f"\n[table]\nfamily_loads_N = {_deep()}\n")},
    ),
    Case(
        "table_deep_json",
        "nesting",
        ("diagnose", "good.csv", "--table-in", "b.json"),
        ("b.json", "nested"),
        files={"b.json": _text('{"format": ' + _deep(100_000) + "}")},
    ),
    Case(
        "sweep_deep_axes",
        "nesting",
        ("sweep", "s.toml", "--serial"),
        ("s.toml", "nested"),
        files={"s.toml": _text(_sweep(f'"stand.ball_loads_N" = {_deep()}'))},
    ),
    # traces the loader must refuse (content)
    Case(
        "emps_2d_variables",
        "trace",
        ("diagnose", "e.mat"),
        ("e.mat", "variable", "matrix"),
        files={"e.mat": _emps_matrix},
    ),
    Case(
        "position_in_mm",
        "trace",
        ("diagnose", "mm.csv"),
        ("mm.csv", "position_m", "--map"),
        files={"mm.csv": _text(_trace_with(1, lambda v, i: 1e3 * v))},
    ),
    Case(
        "force_nan",
        "trace",
        ("diagnose", "n.csv"),
        ("n.csv", "row 12", "force_N"),
        files={"n.csv": _text(_trace_with(2, lambda v, i: float("nan") if i == 10 else v))},
    ),
    Case(
        "time_backwards",
        "trace",
        ("diagnose", "b.csv"),
        ("b.csv", "time_s"),
        files={"b.csv": _text(_trace_with(0, lambda v, i: 0.5 if i == 700 else v))},
    ),
    Case(
        "missing_force",
        "trace",
        ("diagnose", "m.csv"),
        ("m.csv", "force_N"),
        files={"m.csv": _text(_trace_with(2, lambda v, i: v, "time_s,position_m,torque"))},
    ),
    Case(
        "garbage_mat",
        "trace",
        ("diagnose", "g.mat"),
        ("g.mat", "MATLAB"),
        files={"g.mat": _bytes(b"MATLAB 5.0 MAT-file" + bytes(range(256)) * 4)},
    ),
    Case(
        "constant_force",
        "trace",
        ("diagnose", "c.csv"),
        ("c.csv", "force"),
        files={"c.csv": _text(_trace_with(2, lambda v, i: 1.5))},
    ),
    # command-line values
    Case(
        "scheduler_not_a_url",
        "cli",
        ("sweep", "s.toml", "--scheduler", "not a url"),
        ("--scheduler", "not a scheduler address"),
        files={"s.toml": _text(_sweep('"stand.ball_loads_N" = [50.0]'))},
    ),
    Case(
        "workers_0",
        "cli",
        ("sweep", "s.toml", "--workers", "0"),
        ("--workers",),
        files={"s.toml": _text(_sweep('"stand.ball_loads_N" = [50.0]'))},
    ),
    Case(
        "tls_without_certs",
        "cli",
        ("sweep", "s.toml", "--scheduler", "tls://127.0.0.1:9"),
        ("--tls-ca-file",),
        files={"s.toml": _text(_sweep('"stand.ball_loads_N" = [50.0]'))},
    ),
    Case(
        "sweep_output_is_a_file",
        "cli",
        ("sweep", "s.toml", "--serial", "-o", "good.csv"),
        ("good.csv", "is a file"),
        files={"s.toml": _text(_sweep('"stand.ball_loads_N" = [50.0]'))},
    ),
    Case(
        "table_elements_text",
        "cli",
        ("table", "-o", "t.json", "--elements", "many"),
        ("--elements",),
    ),
    Case(
        "table_output_missing_folder",
        "cli",
        ("table", "-o", "no/such/t.json", "--elements", "2"),
        ("no/such",),
    ),
    Case(
        "map_is_not_code",
        "cli",
        ("diagnose", "good.csv", "--map", "force_N=__import__('os')"),
        ("--map", "neither a column name nor a number"),
    ),
    Case(
        "profile_missing_folder",
        "cli",
        ("profile", "no/such/p.csv"),
        ("no/such",),
    ),
    # malformed files
    Case(
        "table_truncated",
        "malformed",
        ("diagnose", "good.csv", "--table-in", "b.json"),
        ("b.json", "truncated"),
        files={
            "b.json": lambda p: p.write_bytes((p.parent / "good.table.json").read_bytes()[:300])
        },
    ),
    Case(
        "table_nan",
        "malformed",
        ("diagnose", "good.csv", "--table-in", "b.json"),
        ("b.json", "NaN"),
        files={
            "b.json": lambda p: p.write_text(
                (p.parent / "good.table.json")
                .read_text()
                .replace('"viscous_Ns_per_m": 0.0', '"viscous_Ns_per_m": NaN')
            )
        },
    ),
    Case(
        "table_elements_float",
        "malformed",
        ("diagnose", "good.csv", "--table-in", "b.json"),
        ("b.json", "elements"),
        files={"b.json": _table_edit(lambda d: d.update(elements=1e9))},
    ),
    Case(
        "config_empty",
        "malformed",
        ("model", "c.toml"),
        ("c.toml", "missing required key"),
        files={"c.toml": _text("")},
    ),
    Case(
        "sweep_unknown_section",
        "malformed",
        ("sweep", "s.toml", "--serial"),
        ("s.toml",),
        files={"s.toml": _text(_sweep('"stand.ball_loads_N" = [50.0]') + "[other]\nx = 1\n")},
    ),
    Case("config_is_a_folder", "malformed", ("model", "."), (".",)),
    # issue 74: the audit's bad inputs, each through the real command line
    Case(
        "config_400_digits",
        "schema",
        ("config", "c.toml"),
        ("c.toml", "bearing.ball_radius_m", "401 digits"),
        files={"c.toml": _text(_edit("ball_radius_m", "1" + "0" * 400))},
    ),
    Case(
        "simulate_400_digits",
        "schema",
        ("simulate", "c.toml"),
        ("c.toml", "model.lambda_count"),
        files={"c.toml": _text(_edit("lambda_count", "1" + "0" * 400))},
    ),
    Case(
        "table_in_400_digits",
        "schema",
        ("diagnose", "good.csv", "--table-in", "b.json"),
        ("b.json", "viscous_Ns_per_m", "401 digits"),
        files={"b.json": _table_edit(lambda d: d.update(viscous_Ns_per_m=10**400))},
    ),
    Case(
        "table_negative_seed",
        "schema",
        ("table", "c.toml", "-o", "t.json"),
        ("c.toml", "table.random_seed"),
        files={"c.toml": _text(GOOD_CONFIG + "\n[table]\nrandom_seed = -1\n")},
    ),
    Case(
        "simulate_negative_seed",
        "schema",
        ("simulate", "c.toml"),
        ("c.toml", "plant.noise_seed"),
        files={"c.toml": _text(GOOD_CONFIG + "\n[plant]\nnoise_seed = -1\n")},
    ),
    Case(
        "demo_trace_negative_seed", "schema", ("demo-trace", "o.csv", "--seed", "-1"), ("--seed",)
    ),
    Case(
        "ramp_time_1e300",
        "schema",
        ("stream", "c.toml", "--duration", "0.2"),
        ("c.toml", "can.ramp_time_s"),
        files={"c.toml": _text(GOOD_CONFIG + CAN + "ramp_time_s = 1e300\n")},
    ),
    Case(
        "dwell_1e9",
        "schema",
        ("simulate", "c.toml"),
        ("c.toml", "scenario.dwell_s"),
        files={
            "c.toml": _text(GOOD_CONFIG + '\n[scenario]\ntrajectory = "step_stop"\ndwell_s = 1e9\n')
        },
    ),
    Case(
        "config_agrees_with_model",
        "schema",
        ("config", "c.toml"),
        ("c.toml", "stand.ball_loads_N[0]", "contact ellipse"),
        files={
            "c.toml": _text(
                _edit(
                    "youngs_modulus_raceway_Pa",
                    "1e8",
                    _edit("youngs_modulus_ball_Pa", "1e8", _edit("ball_loads_N", "[2000.0]")),
                )
            )
        },
    ),
    *(
        Case(
            f"replay_model_{name}",
            "schema",
            ("replay", "good.csv", "--model", "m.json"),
            ("m.json", field),
            files={"m.json": build},
        )
        for name, field, build in (
            (
                "zero_mass",
                "mass_kg",
                _table_edit(
                    lambda d: d.update(
                        extensions=[{"effect": "inertia", "parameters": {"mass_kg": 0.0}}]
                    )
                ),
            ),
            (
                "negative_mass",
                "mass_kg",
                _table_edit(
                    lambda d: d.update(
                        extensions=[{"effect": "inertia", "parameters": {"mass_kg": -5.0}}]
                    )
                ),
            ),
            (
                "zero_length",
                "length_m",
                _table_edit(
                    lambda d: d.update(
                        extensions=[
                            {
                                "effect": "reversal_transient",
                                "parameters": {"amplitude_N": 1.0, "length_m": 0.0},
                            }
                        ]
                    )
                ),
            ),
            (
                "missing_parameter",
                "parameters",
                _table_edit(
                    lambda d: d.update(
                        extensions=[{"effect": "stribeck", "parameters": {"ratio": 1.5}}]
                    )
                ),
            ),
            (
                "offset_1e12",
                "offset_N",
                _table_edit(
                    lambda d: d.update(
                        extensions=[{"effect": "offset", "parameters": {"offset_N": 1e12}}]
                    )
                ),
            ),
            ("deep", "nested", _text("[" * 100_000 + "]" * 100_000)),
            (
                "400_digits",
                "viscous_Ns_per_m",
                _table_edit(lambda d: d.update(viscous_Ns_per_m=10**400)),
            ),
            (
                "baseline_zero_mass",
                "baseline.mass_kg",
                _text(
                    json.dumps(
                        {
                            "baseline": {
                                "breakaway_m": [1e-6],
                                "limit_N": [1.0],
                                "slip_level": 1.2,
                                "mass_kg": 0,
                            }
                        }
                    )
                ),
            ),
        )
    ),
    # issue 74: outputs that would overwrite an input or are not regular files
    Case(
        "diagnose_table_over_trace",
        "outputs",
        ("diagnose", "good.csv", "--table", "good.csv"),
        ("--table", "good.csv", "input"),
    ),
    Case(
        "table_over_config",
        "outputs",
        ("table", "c.toml", "-o", "c.toml"),
        ("c.toml", "input"),
        files={"c.toml": _text(GOOD_CONFIG)},
    ),
    Case(
        "simulate_over_config",
        "outputs",
        ("simulate", "c.toml", "-o", "c.toml"),
        ("c.toml", "input"),
        files={"c.toml": _text(GOOD_CONFIG)},
    ),
    Case(
        "stream_over_config",
        "outputs",
        ("stream", "c.toml", "-o", "c.toml"),
        ("c.toml", "input"),
        files={"c.toml": _text(GOOD_CONFIG)},
    ),
    Case(
        "stream_log_is_report",
        "outputs",
        ("stream", "--log", "f.csv", "-o", "f.csv"),
        ("f.csv", "another output"),
    ),
    Case(
        "output_fifo",
        "outputs",
        ("table", "-o", "fifo"),
        ("fifo", "not a regular file"),
        files={"fifo": lambda p: os.mkfifo(p)},
    ),
    Case("output_dev_null", "outputs", ("table", "-o", "/dev/null"), ("/dev/null", "under /dev")),
    Case("output_proc_fd", "outputs", ("simulate", "-o", "/proc/self/fd/1"), ("under /proc",)),
    Case("plot_suffix_xyz", "outputs", ("simulate", "--plot", "out.xyz"), ("--plot", ".xyz")),
    Case("plot_without_suffix", "outputs", ("simulate", "--plot", "out"), ("--plot", "no suffix")),
    Case("log_suffix_xyz", "outputs", ("stream", "--log", "frames.xyz"), ("--log", ".xyz")),
    Case(
        "report_holds_input",
        "outputs",
        ("diagnose", "rep/t.csv", "--report", "rep"),
        ("--report", "rep/t.csv"),
        files={"rep": _report_with_trace},
    ),
    # issue 74: nothing from a file decides where code runs
    Case(
        "sweep_file_scheduler",
        "scheduler",
        ("sweep", "s.toml", "-o", "fam"),
        ("s.toml", "scaleout", "--scheduler"),
        files={
            "s.toml": _text(
                _sweep('"stand.ball_loads_N" = [50.0]')
                + '[scaleout]\nscheduler = "tcp://127.0.0.1:9"\n'
            )
        },
    ),
    Case(
        "plain_tcp_scheduler",
        "scheduler",
        ("sweep", "s.toml", "--scheduler", "tcp://127.0.0.1:9", "-o", "fam"),
        ("--scheduler", "--insecure-scheduler"),
        files={"s.toml": _text(_sweep('"stand.ball_loads_N" = [50.0]'))},
    ),
    Case(
        "tcp_scheduler_with_tls_files",
        "scheduler",
        (
            "sweep",
            "s.toml",
            "--scheduler",
            "tcp://127.0.0.1:9",
            "--tls-ca-file",
            "s.toml",
            "--tls-cert",
            "s.toml",
            "--tls-key",
            "s.toml",
            "-o",
            "fam",
        ),
        ("--scheduler", "plain tcp"),
        files={"s.toml": _text(_sweep('"stand.ball_loads_N" = [50.0]'))},
    ),
]


def _param(case: Case) -> Any:
    return pytest.param(case, id=case.id)


# --- running ------------------------------------------------------------------------------


def _prepare(folder: Path) -> None:
    """The good files every case starts from: a small trace and a table from the CLI."""
    (folder / "good.csv").write_text(_csv(_good_trace_rows()))
    subprocess.run(
        [sys.executable, "-m", "gms_comp", "table", "--elements", "2", "-o", "good.table.json"],
        cwd=folder,
        check=True,
        capture_output=True,
        timeout=120,
    )


def _case_dir(root: Path, case: Case) -> Path:
    """The case's folder with the good files and its bad ones (made once)."""
    folder = root / case.id
    if folder.is_dir():
        return folder
    folder.mkdir()
    for name in ("good.csv", "good.table.json"):
        (folder / name).write_bytes((root / name).read_bytes())
    for name, build in case.files.items():
        build(folder / name)
    return folder


def run_forked(root: Path, cases: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Run command lines through tests/cli_runner.py (one fork per case, memory cap)."""
    todo, done = root / "cases.json", root / "results.json"
    todo.write_text(json.dumps(cases))
    subprocess.run([sys.executable, str(RUNNER), str(todo), str(done)], check=True, timeout=1800)
    results: list[dict[str, Any]] = json.loads(done.read_text())
    return results


def run_subprocess(folder: Path, argv: tuple[str, ...]) -> dict[str, Any]:
    """One command line in a fresh interpreter: ``python -m gms_comp`` under the cap."""
    sys.path.insert(0, str(RUNNER.parent))
    from cli_runner import limit_memory

    try:
        proc = subprocess.run(
            [sys.executable, "-m", "gms_comp", *argv],
            cwd=folder,
            capture_output=True,
            text=True,
            timeout=TIME_BOUND_S + 30,
            preexec_fn=limit_memory,
            stdin=subprocess.DEVNULL,
        )
    except subprocess.TimeoutExpired:
        return {"rc": None, "stdout": "", "stderr": "", "timed_out": True}
    return {"rc": proc.returncode, "stdout": proc.stdout, "stderr": proc.stderr, "timed_out": False}


def error_lines(stderr: str) -> list[str]:
    """The non-blank lines of stderr (a refusal is exactly one, usage block included)."""
    return [line for line in stderr.splitlines() if line.strip()]


def outcome(result: dict[str, Any]) -> str:
    """Classify one run (see the module docstring)."""
    if result["timed_out"]:
        return "hang"
    err = result["stderr"]
    if "Traceback (most recent call last)" in err or "MemoryError" in err:
        return "traceback"
    rc = result["rc"]
    if rc == 2:
        return "refused" if len(error_lines(err)) == 1 else "multi-line"
    if rc in (0, 1):
        return "accepted"
    return "crash"


@pytest.fixture(scope="module")
def fuzz_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("fuzz")
    _prepare(root)
    return root


@pytest.fixture(scope="module")
def forked_results(fuzz_root: Path) -> dict[str, dict[str, Any]]:
    cases = [
        {
            "id": c.id,
            "argv": list(c.argv),
            "cwd": str(_case_dir(fuzz_root, c)),
            "timeout_s": TIME_BOUND_S,
        }
        for c in CASES
    ]
    results = run_forked(fuzz_root, cases)
    counts = Counter((c.cls, outcome(r)) for c, r in zip(CASES, results, strict=True))
    (fuzz_root / "summary.json").write_text(
        json.dumps({f"{k[0]}:{k[1]}": v for k, v in sorted(counts.items())}, indent=1)
    )
    return {r["id"]: r for r in results}


def _check(case: Case, result: dict[str, Any]) -> None:
    got = outcome(result)
    assert got == "refused", f"{case.id}: {got}, rc {result['rc']}: {result['stderr'][-2000:]}"
    line = error_lines(result["stderr"])[0]
    assert line.startswith("gms-comp "), line
    for name in case.names:
        assert name in line, f"{case.id}: {name!r} not in {line!r}"


@pytest.mark.parametrize("case", [_param(c) for c in CASES])
def test_bad_input_is_refused_in_one_line(
    case: Case, forked_results: dict[str, dict[str, Any]]
) -> None:
    _check(case, forked_results[case.id])


def test_every_audit_class_is_covered() -> None:
    classes = Counter(c.cls for c in CASES)
    assert set(classes) == {
        "extreme",
        "resources",
        "non-utf8",
        "nesting",
        "trace",
        "cli",
        "malformed",
        "schema",
        "outputs",
        "scheduler",
    }
    assert all(n >= 3 for n in classes.values()), classes


SPOT_CHECKS = ("config_400_digits", "config_latin1", "sweep_workers_-1")


@pytest.mark.parametrize("case_id", SPOT_CHECKS)
def test_a_fresh_interpreter_gives_the_same_outcome(
    case_id: str, fuzz_root: Path, forked_results: dict[str, dict[str, Any]]
) -> None:
    """The fork runner is the real CLI: a fresh ``python -m gms_comp`` prints the same."""
    case = next(c for c in CASES if c.id == case_id)
    fresh = run_subprocess(_case_dir(fuzz_root, case), case.argv)
    assert outcome(fresh) == outcome(forked_results[case.id]) == "refused"
    assert error_lines(fresh["stderr"]) == error_lines(forked_results[case.id]["stderr"])


# --- slow: every case in a fresh interpreter, and random mutations ------------------------


@pytest.mark.slow
@pytest.mark.parametrize("case", [_param(c) for c in CASES])
def test_bad_input_is_refused_by_a_fresh_interpreter(case: Case, fuzz_root: Path) -> None:
    _check(case, run_subprocess(_case_dir(fuzz_root, case), case.argv))


def _mutate(data: bytes, rng: random.Random) -> bytes:
    """One random mutation: flip, insert, delete, duplicate or truncate bytes."""
    buf = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        if not buf:
            break
        i = rng.randrange(len(buf))
        kind = rng.randrange(6)
        if kind == 0:
            buf[i] ^= 1 << rng.randrange(8)
        elif kind == 1:
            buf[i:i] = bytes(
                rng.choice(b"[]{}\"',.=-e9\n\x00\xff") for _ in range(rng.randint(1, 8))
            )
        elif kind == 2:
            del buf[i : i + rng.randint(1, 16)]
        elif kind == 3:
            j = rng.randrange(len(buf))
            buf[i:i] = buf[j : j + rng.randint(1, 64)]
        elif kind == 4:
            del buf[i:]
        else:
            digits = rng.choice([b"1e300", b"-1", b"0", b"1e-300", b"nan", b"99999999999"])
            buf[i:i] = digits
    return bytes(buf)


MUTATED = {
    "config": ("c.toml", ("model", "c.toml")),
    "table": ("b.json", ("diagnose", "good.csv", "--table-in", "b.json")),
    "trace": ("t.csv", ("diagnose", "t.csv")),
    "sweep": ("s.toml", ("sweep", "s.toml", "--serial", "-o", "fam")),
}


@pytest.mark.slow
def test_random_mutations_never_crash(fuzz_root: Path) -> None:
    """Mutated good files: refused in one line or accepted, never a traceback or a hang."""
    rng = random.Random(1312)
    sources = {
        "config": GOOD_CONFIG.encode(),
        "table": (fuzz_root / "good.table.json").read_bytes(),
        "trace": (fuzz_root / "good.csv").read_bytes(),
        "sweep": _sweep('"stand.ball_loads_N" = [50.0]').encode(),
    }
    cases = []
    for i in range(160):
        kind = list(MUTATED)[i % len(MUTATED)]
        name, argv = MUTATED[kind]
        folder = fuzz_root / f"mut{i:03d}"
        folder.mkdir()
        for good in ("good.csv", "good.table.json"):
            (folder / good).write_bytes((fuzz_root / good).read_bytes())
        (folder / name).write_bytes(_mutate(sources[kind], rng))
        cases.append(
            {"id": f"mut{i:03d}-{kind}", "argv": list(argv), "cwd": str(folder), "timeout_s": 120.0}
        )
    results = run_forked(fuzz_root, cases)
    bad = [
        (r["id"], outcome(r), r["stderr"][-600:])
        for r in results
        if outcome(r) not in ("refused", "accepted")
    ]
    counts = Counter(outcome(r) for r in results)
    by_kind = Counter((r["id"].split("-", 1)[1], outcome(r)) for r in results)
    print("mutation outcomes:", dict(sorted(by_kind.items())))  # shown with pytest -s
    assert not bad, f"{counts}: {bad[:5]}"
