"""``gms-comp commission``: from nothing to a compensated axis, on a bus with no NC running.

It drives the axis itself (NMT start, the CiA 402 enable sequence, cyclic synchronous
position as SYNC master; the axis is left stopped and disabled after each step, also on
Ctrl-C): it records the identification profile, diagnoses it (the cause of what the ball
model does not explain, the extended model), then runs the ``[scenario]`` reversal test
once per feedforward: none, Coulomb+viscous fitted to the recording, the physics table
(the ball model, whole guide), the extended table (the physics GMS with the effects
found) and the calibrated one (the GMS as the diagnosis calibrated it, with the effects),
and deploys the table with the smallest peak reversal error. It reports the cause and the
gain in um: a summary on stdout (``--json``: the whole document), ``--report DIR`` a JSON
and a self-contained HTML page with plots, ``--table OUT`` the deployed table for
``gms-comp run``.

Against the simulated machine: ``gms-comp machine --interface udp_multicast --channel
ff11::4743:4d53`` in one terminal, this command with the same interface and channel in
another; against a real drive: ``--interface socketcan --channel can0``.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

from gms_comp.app.commands.diagnose import extended_table
from gms_comp.app.live.arguments import add_bus_arguments, bus_config
from gms_comp.app.live.commission import commission
from gms_comp.app.live.recording import nc_on_bus
from gms_comp.app.signals import stop_requests
from gms_comp.arguments import output_dir, output_file
from gms_comp.errors import BusError
from gms_comp.measured.diagnosis.result import parameter_text
from gms_comp.tables.table import write_table
from sim.scenarios import load_scenario


def register(subparsers: Any) -> None:
    """Add ``commission`` to the CLI."""
    p = subparsers.add_parser(
        "commission",
        help="record, diagnose and verify an axis on the CAN bus (no NC running)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_bus_arguments(p)
    p.add_argument(
        "--scale",
        type=float,
        default=1.0,
        choices=(0.25, 0.5, 1.0),
        help="length of the identification profile (1.0: about 40 s)",
    )
    p.add_argument(
        "--in-drive",
        action="store_true",
        help="also download each table into the drive (SDO, 0x2100) and test it run there, "
        "at the drive's servo rate on its position command (a drive with the gms-comp "
        "observer), and deploy the best of those",
    )
    p.add_argument("--json", action="store_true", help="print the document as JSON on stdout")
    p.add_argument("--report", type=output_dir, metavar="DIR", help="write JSON and HTML here")
    p.add_argument("--table", type=output_file, metavar="OUT", help="write the deployed table")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Commission the axis on the bus; report the cause and the gain."""
    path, cfg = bus_config(args)
    s = load_scenario(path)
    cfg = replace(cfg, profile="cia402", sync_master=True)
    if nc_on_bus(cfg):
        raise BusError(
            f"an NC produces SYNC on {cfg.interface} {cfg.channel!r}: commission drives the "
            "axis itself only when no NC runs (use gms-comp record and run beside an NC)"
        )

    def say(message: str) -> None:
        print(f"commission: {message}", file=sys.stderr, flush=True)

    with stop_requests() as stop, stop.deferred() as stopping:
        result = commission(cfg, s, lambda r: extended_table(r, path), args.scale, stopping, say,
                            in_drive=args.in_drive)  # fmt: skip
    doc = result.to_json()
    doc["interrupted"] = stopping.is_set()
    written: list[Path] = []
    if args.table is not None:
        write_table(args.table, result.deployed_table)
        written.append(Path(args.table))
    if args.report is not None:
        from gms_comp.app.live.report import write_report  # matplotlib only when asked for

        written += write_report(result, doc, Path(args.report), cfg.cycle_period_s)
    if args.json:
        print(json.dumps(doc, indent=2))
    else:
        print(summary(doc))
    for p in written:
        print(f"wrote {p}", file=sys.stderr if args.json else sys.stdout)
    return stop.exit_code if stop.signum is not None else 0


def summary(doc: dict[str, Any]) -> str:
    """The cause found and the reversal errors per feedforward, in um."""
    diag = doc["diagnosis"]
    effects = ", ".join(
        f"{e['effect']} ({', '.join(parameter_text(k, v) for k, v in e['parameters'].items())})"
        for e in diag["effects"]
    )
    rec = doc["recording"]
    lines = [
        f"recorded {rec['samples']} samples ({rec['samples_missing']} missing)",
        f"cause: {diag['effect']}" + (f": {effects}" if effects else ""),
        f"gain: {diag['gain']:.1%} (held-out force RMS {diag['baseline_rms_N']:.3g} N -> "
        f"{diag['extended_rms_N']:.3g} N, noise {diag['noise_rms_N']:.3g} N)",
        "reversal test, peak / RMS following error:",
    ]
    for name, v in doc["verification"].items():
        peak = v["peak_reversal_error_m"]
        lines.append(
            f"  {name:16s} {'-' if peak is None else f'{peak * 1e6:8.3f}'} um / "
            f"{v['rms_error_m'] * 1e6:8.3f} um"
        )
    where = " in the drive" if doc.get("deployed_in_drive") else ""
    lines.append(
        f"deployed: {doc['deployed']}{where} (the table with the smallest peak reversal error)"
    )
    return "\n".join(lines)
