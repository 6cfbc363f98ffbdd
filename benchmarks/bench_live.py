"""The live bus, measured across processes: commission, run and record against the machine.

Every run starts ``gms-comp machine`` in its own process on python-can's ``udp_multicast``
(loopback) and talks to it from this one, as a user would from two terminals:

- ``commission``, with a hidden ``position_ripple``, ``reversal_transient`` and
  ``viscous`` in turn: the effect named, its main parameter's error, the reversal test's
  peak and RMS error per feedforward (over the bus, and each table in the drive), the table
  deployed and the ratios the issue targets (the extended table against none and against
  the physics table, over the bus and in the drive);
- ``run`` at 1 kHz against ``gms-comp machine --nc``: the share of SYNCs answered within
  the cycle, SYNC-to-frame p50/p99, stale or foreign frames the drive applied, and the
  tracking error with the deployed table (of the ripple commissioning) against none;
- ``record`` under dropped and delayed TPDOs: samples, lost, late;
- the observer in the drive (the table downloaded, the servo at 4, 8, 16 kHz) against
  the feedforward over CAN at 1 kHz with and without look-ahead, stepped over the bus;
- the ceiling of each hidden effect's target: the reversal test stepped with the physics
  table extended by the effect's true parameters (what a perfect diagnosis would
  deploy), against none and the physics table alone.

Prints one JSON document. Real time on a shared 2-core machine: run it idle.

    python benchmarks/bench_live.py [--scale 0.25] [--only commission|run|record|in_drive|truth]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from gms_comp.config import default_config_path

GROUP = "ff11::4743:4d53"
BUS = ["--interface", "udp_multicast", "--channel", GROUP]
EFFECTS: dict[str, tuple[dict[str, float], str, float]] = {
    # effect: (its parameters, the main parameter, its true value)
    "position_ripple": ({"amplitude_N": 2.0, "wavelength_m": 2e-3, "phase_rad": 0.4},
                        "wavelength_m", 2e-3),
    "reversal_transient": ({"amplitude_N": 4.0, "length_m": 4e-5}, "amplitude_N", 4.0),
    "viscous": ({"c_Ns_per_m": 150.0}, "c_Ns_per_m", 150.0),
}  # fmt: skip


def config(folder: Path, effect: str, parameters: dict[str, float]) -> Path:
    lines = [f'effect = "{effect}"', *(f"{k} = {v!r}" for k, v in parameters.items())]
    path = folder / f"{effect}.toml"
    path.write_text(default_config_path().read_text() + "\n[machine]\n" + "\n".join(lines) + "\n")
    return path


@contextmanager
def machine(path: Path, *extra: str) -> Iterator[subprocess.Popen[str]]:
    cmd = [sys.executable, "-m", "gms_comp", "machine", str(path), *BUS, "--json", *extra]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stderr is not None
        line = proc.stderr.readline()
        if not line.startswith("ready"):
            raise RuntimeError(f"the machine did not start: {line}")
        yield proc
    finally:
        proc.terminate()
        proc.communicate(timeout=30)


def cli(*args: str) -> dict[str, Any]:
    done = subprocess.run([sys.executable, "-m", "gms_comp", *args, *BUS, "--json"],
                          capture_output=True, text=True, timeout=1800)  # fmt: skip
    if done.returncode != 0:
        raise RuntimeError(done.stderr.strip().splitlines()[-1])
    doc: dict[str, Any] = json.loads(done.stdout)
    return doc


def commissioning(folder: Path, scale: float) -> dict[str, Any]:
    out = {}
    for effect, (parameters, main, truth) in EFFECTS.items():
        path = config(folder, effect, parameters)
        started = time.monotonic()
        with machine(path):
            doc = cli("commission", str(path), "--scale", str(scale), "--in-drive",
                      "--table", str(folder / f"{effect}.table.json"))  # fmt: skip
        found = {e["effect"]: e["parameters"] for e in doc["diagnosis"]["effects"]}
        v = doc["verification"]
        peak = {k: x["peak_reversal_error_m"] for k, x in v.items()}
        out[effect] = {
            "named": list(found),
            "main_parameter_error": (
                abs(found[effect][main] / truth - 1) if effect in found else None
            ),
            "peak_reversal_error_nm": {k: round(x * 1e9, 1) for k, x in peak.items() if x},
            "rms_error_nm": {k: round(x["rms_error_m"] * 1e9, 1) for k, x in v.items()},
            "deployed": doc["deployed"],
            "extended_over_none": peak["extended"] / peak["none"],
            "extended_over_table": peak["extended"] / peak["table"],
            "extended_in_drive_over_none": peak["extended_in_drive"] / peak["none"],
            "extended_in_drive_over_table_in_drive": (
                peak["extended_in_drive"] / peak["table_in_drive"]
            ),
            "deployed_in_drive": doc["deployed_in_drive"],
            "can": doc["can"]["stale_or_corrupt_applied"],
            "samples_missing": doc["recording"]["samples_missing"],
            "samples": doc["recording"]["samples"],
            "seconds": round(time.monotonic() - started, 1),
        }
        print(f"commission {effect}: {out[effect]}", file=sys.stderr)
    return out


def running(folder: Path) -> dict[str, Any]:
    path = config(folder, "position_ripple", EFFECTS["position_ripple"][0])
    table = folder / "position_ripple.table.json"
    out = {}
    for name, table_arg in (("none", "none"), ("deployed", str(table))):
        if name == "deployed" and not table.exists():
            continue
        with machine(path, "--nc") as proc:
            time.sleep(0.5)
            report = cli("run", str(path), "--table", table_arg, "--duration", "3")
            del proc
        out[name] = {k: report.get(k) for k in (
            "answered_within_cycle", "sync_to_sent_p50_s", "sync_to_sent_p99_s",
            "frames_sent", "inputs_missing", "tracking_rms_error_m", "tracking_peak_error_m",
        )}  # fmt: skip
        print(f"run {name}: {out[name]}", file=sys.stderr)
    return out


def recording(folder: Path) -> dict[str, Any]:
    out = {}
    for faults in ((), ("drop:0.05",), ("delay=3:0.1",)):
        args = [a for f in faults for a in ("--fault", f)]
        with machine(default_config_path(), "--nc"):
            time.sleep(0.3)
            side = cli("record", str(folder / "rec.csv"), "--duration", "3", *args)
        out[" ".join(faults) or "none"] = {k: side[k] for k in ("samples", "samples_missing",
                                                                "lost", "late")}  # fmt: skip
        print(f"record {faults}: {out[' '.join(faults) or 'none']}", file=sys.stderr)
    return out


def in_drive_vs_can() -> dict[str, Any]:
    """Stepped over the bus, the default machine, the physics table: the feedforward over
    CAN at 1 kHz (look-ahead 0 and 1 cycle) against the observer in the drive at its servo
    rate (4, 8, 16 kHz), peak reversal and RMS following error in um."""
    import dataclasses

    from firmware_bridge.profiles.cia402.drive import Cia402Drive
    from firmware_bridge.settings import load_can_config
    from gms_comp.app.live.commission import physics_table, verify
    from sim.machine import CspAxis, load_machine

    out: dict[str, Any] = {}
    for rate in (4000.0, 8000.0, 16000.0):
        m = load_machine()
        s = m.scenario
        s = dataclasses.replace(s, controller=dataclasses.replace(s.controller, servo_rate_Hz=rate))
        m = dataclasses.replace(m, scenario=s)
        cfg = dataclasses.replace(load_can_config(), channel=f"bench-in-drive-{rate:g}")

        def drive(c: Any, bus: Any, m: Any = m) -> Cia402Drive:
            return Cia402Drive(c, bus, CspAxis(m, c.cycle_period_s))

        table = physics_table(s)
        runs = {f"in_drive_{rate / 1e3:g}kHz": verify(cfg, s, "in", table, None, drive, True)}
        if rate == 4000.0:
            runs["none"] = verify(cfg, s, "none", None, None, drive)
            for ahead in (0, 1):
                comp = dataclasses.replace(s.compensator, look_ahead_cycles=ahead)
                s_ahead = dataclasses.replace(s, compensator=comp)
                runs[f"can_1kHz_lookahead_{ahead}"] = verify(cfg, s_ahead, "can", table, None,
                                                             drive)  # fmt: skip
        for name, v in runs.items():
            out[name] = {
                "peak_reversal_error_um": round((v.peak_reversal_error_m or 0) * 1e6, 4),
                "rms_error_um": round(v.rms_error_m * 1e6, 4),
            }
            print(f"in drive vs CAN {name}: {out[name]}", file=sys.stderr)
    return out


def truth_ceiling() -> dict[str, Any]:
    """Per hidden effect, stepped over the bus: the reversal test with none, the physics
    table, and the table extended by the effect's true parameters (peak and RMS in nm)."""
    import dataclasses

    from firmware_bridge.profiles.cia402.drive import Cia402Drive
    from firmware_bridge.settings import load_can_config
    from gms_comp.app.live.commission import physics_table, verify
    from gms_comp.tables.table import Extension
    from sim.machine import CspAxis, load_machine

    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for effect, (parameters, _, _) in EFFECTS.items():
            m = load_machine(config(Path(tmp), effect, parameters))
            cfg = dataclasses.replace(load_can_config(), channel=f"bench-truth-{effect}")

            def drive(c: Any, bus: Any, m: Any = m) -> Cia402Drive:
                return Cia402Drive(c, bus, CspAxis(m, c.cycle_period_s))

            table = physics_table(m.scenario)
            truth = dataclasses.replace(table, extensions=(Extension(effect, parameters),))
            runs = {
                name: verify(cfg, m.scenario, name, model, None, drive)
                for name, model in (("none", None), ("table", table), ("truth", truth))
            }
            peak = {k: (v.peak_reversal_error_m or math.nan) * 1e9 for k, v in runs.items()}
            out[effect] = {
                "peak_reversal_error_nm": {k: round(x, 1) for k, x in peak.items()},
                "rms_error_nm": {k: round(v.rms_error_m * 1e9, 1) for k, v in runs.items()},
                "truth_over_none": round(peak["truth"] / peak["none"], 3),
                "truth_over_table": round(peak["truth"] / peak["table"], 3),
            }
            print(f"truth ceiling {effect}: {out[effect]}", file=sys.stderr)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scale", type=float, default=0.25, choices=(0.25, 0.5, 1.0))
    parser.add_argument("--only", choices=("commission", "run", "record", "in_drive", "truth"))
    args = parser.parse_args()
    doc: dict[str, Any] = {"load_1min_start": os.getloadavg()[0]}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if args.only in (None, "commission", "run"):
            doc["commission"] = commissioning(folder, args.scale)
        if args.only in (None, "run"):
            doc["run"] = running(folder)
        if args.only in (None, "record"):
            doc["record"] = recording(folder)
        if args.only in (None, "in_drive"):
            doc["in_drive_vs_can"] = in_drive_vs_can()
        if args.only in (None, "truth"):
            doc["truth_ceiling"] = truth_ceiling()
    doc["load_1min_end"] = os.getloadavg()[0]
    print(json.dumps(doc, indent=2))


if __name__ == "__main__":
    main()
