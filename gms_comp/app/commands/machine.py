"""``gms-comp machine``: a simulated machine axis as a CiA 402 drive on the bus.

The drive is a CANopen device like a real one (canopen's LocalNode from the packaged
EDS: SDO, NMT, heartbeat, EMCY, the CiA 402 state machine, PDOs at every SYNC) hosting
the simulated axis in cyclic synchronous position: the plant with the full ball model as
friction plus the ``[machine]`` section's hidden effect, under the drive's own
position/velocity loop. ``--nc`` adds the NC: SYNC and the CSP target positions along a
part program (a CSV as ``gms-comp profile`` writes, or the ``[scenario]`` trajectory), run
back and forth until the machine stops.
Without ``--nc`` the drive waits for an NC, or for ``gms-comp record`` / ``commission``,
which drive it themselves.

Run it in its own terminal (``--interface udp_multicast --channel ff11::4743:4d53``
across processes on one machine; ``socketcan``/``pcan``/... for a real bus); it prints
``ready`` once on the bus, runs until ``--duration`` ends or Ctrl-C/SIGTERM, then prints
its status (``--json``: as JSON).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from gms_comp.app.live.arguments import add_bus_arguments, bus_config, checked_duration
from gms_comp.app.live.machine import machine_on_bus, read_program, scenario_program
from gms_comp.app.signals import stop_requests
from sim.machine import load_machine

MAX_DURATION_S = 24 * 3600.0
SCENARIO = "scenario"


def register(subparsers: Any) -> None:
    """Add ``machine`` to the CLI."""
    p = subparsers.add_parser(
        "machine",
        help="run a simulated machine axis as a CiA 402 drive on the CAN bus",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_bus_arguments(p)
    p.add_argument(
        "--nc",
        nargs="?",
        const=SCENARIO,
        metavar="PROGRAM.csv",
        help="also play the NC: SYNC and targets along PROGRAM.csv (time_s, position_m), "
        "or the config's [scenario] without a file",
    )
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="S",
        help="stop after S seconds (default: run until Ctrl-C or SIGTERM)",
    )
    p.add_argument("--json", action="store_true", help="print the final status as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Put the machine on the bus until the duration ends or a signal asks it to stop."""
    duration = checked_duration(
        args.duration if args.duration is not None else MAX_DURATION_S, MAX_DURATION_S
    )
    path, cfg = bus_config(args)
    machine = load_machine(path)
    program = None
    if args.nc == SCENARIO:
        program = scenario_program(machine, cfg.cycle_period_s)
    elif args.nc is not None:
        program = read_program(Path(args.nc), cfg.cycle_period_s)
    with stop_requests() as stop, machine_on_bus(machine, cfg, program) as node:
        effect = machine.config.effect
        print(
            f"ready: machine drive node {cfg.drive_node_id} on {cfg.interface} "
            f"{cfg.channel!r}, {cfg.cycle_period_s * 1e3:g} ms cycle, hidden effect "
            f"{effect}" + (", NC with its part program" if program is not None else ""),
            file=sys.stderr if args.json else sys.stdout,
            flush=True,
        )
        with stop.deferred() as stopping:
            stopping.wait(duration)
        status = node.status()
    status["stopped_by"] = stop.name or "duration"
    if args.json:
        print(json.dumps(status, indent=2, sort_keys=True))
    else:
        print(
            f"machine stopped ({status['stopped_by']}): state {status['state']}, "
            f"feedforward frames applied {status['frames_applied']}, emcy "
            + (", ".join(f"{code} x{n}" for code, n in status["emcy"].items()) or "none")
        )
    return stop.exit_code if stop.signum is not None else 0
