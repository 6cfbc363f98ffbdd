"""``gms-comp stream``: stream the feedforward over CAN to a drive, by default the emulator.

The feedforward comes from the GMS observer run along the config's sine
trajectory at the CAN cycle rate.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

from firmware_bridge.faults import parse_fault
from firmware_bridge.profiles import PROFILES
from firmware_bridge.session import FeedforwardSource, Rig, stream_on
from firmware_bridge.settings import CanConfig, load_can_config
from gms_comp.config import default_config_path
from gms_comp.errors import GmsCompError


def register(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "stream",
        help="stream the feedforward over CAN (default: to the built-in drive emulator)",
        description=__doc__,
    )
    p.add_argument("config", nargs="?", type=Path, help="config file (default: Table 1)")
    p.add_argument("--profile", choices=tuple(PROFILES), help="override [can] profile")
    p.add_argument("--interface", help="python-can interface (virtual, socketcan, pcan, ...)")
    p.add_argument("--channel", help="python-can channel")
    p.add_argument("--duration", type=float, default=2.0, metavar="S", help="seconds (2)")
    p.add_argument(
        "--fault",
        action="append",
        default=[],
        metavar="SPEC",
        help="KIND[:PROBABILITY][@START-END], KIND in drop, delay, duplicate, "
        "reorder, corrupt, stall, bus_error; repeatable",
    )
    p.add_argument(
        "--external-drive",
        action="store_true",
        help="a drive is already on the bus (a real one, or python -m firmware_bridge.emulator):"
        " do not start the built-in emulator; drive-side figures are then null",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the fault injector")
    p.add_argument("--json", type=Path, metavar="OUT", help="write the report as JSON")
    p.add_argument("--log", type=Path, metavar="FILE.blf", help="log all frames (blf, asc, ...)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    config_path = args.config if args.config is not None else default_config_path()
    cfg = load_can_config(config_path)
    overrides = {
        k: v
        for k, v in (
            ("profile", args.profile),
            ("interface", args.interface),
            ("channel", args.channel),
        )
        if v is not None
    }
    cfg = replace(cfg, **overrides)
    if not (math.isfinite(args.duration) and args.duration > 0):
        raise GmsCompError(f"--duration must be a number of seconds > 0, got {args.duration}")
    faults = [parse_fault(spec) for spec in args.fault]
    # the rig opens first: another compensator on the channel is refused before the work
    with Rig(cfg, faults, args.seed, args.log, builtin_drive=not args.external_drive) as rig:
        source = gms_observer_source(config_path, cfg, args.duration)
        report = stream_on(rig, source, args.duration)
    report["source"] = "gms_observer"
    text = json.dumps(report, indent=2, sort_keys=True)
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(text + "\n")
    print(text)
    unsafe = (report["stale_or_corrupt_applied"] or 0) > 0 or (
        (report["max_applied_current_A"] or 0.0) > cfg.max_current_A + 1e-9
    )
    return 1 if unsafe else 0


def gms_observer_source(config_path: Path, cfg: CanConfig, duration_s: float) -> FeedforwardSource:
    """The GMS observer's feedforward along the config's sine, sampled at the CAN cycle."""
    from gms_comp.observer import FrictionObserver
    from sim.scenarios import load_scenario, reduced_table
    from sim.trajectories import sine

    s = load_scenario(config_path)
    c = s.scenario
    observer = FrictionObserver(
        reduced_table(s),
        s.plant.force_constant_N_per_A,
        cfg.cycle_period_s,
        s.plant.ball_set_count * s.compensator.friction_level_scale,
        s.compensator,
    )
    ref = sine(
        c.amplitude_m,
        c.frequency_Hz,
        max(1.0, duration_s * c.frequency_Hz),
        cfg.cycle_period_s,
        c.acceleration_window_s,
        c.jerk_window_s,
        c.dwell_s,
    )
    x, v = ref.position_m.tolist(), ref.velocity_m_s.tolist()
    ahead = s.compensator.look_ahead_cycles

    def source(t_s: float) -> float:
        k = min(round(t_s / cfg.cycle_period_s) + ahead, len(x) - 1)
        return observer.step(x[k], v[k])

    return source
