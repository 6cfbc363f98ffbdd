"""``gms-comp stream``: stream the feedforward over CAN to a drive, by default the emulator.

The feedforward comes from the GMS observer run along the config's sine
trajectory at the CAN cycle rate. A short summary goes to stdout (``--json``:
the full report as JSON instead); ``-o`` writes the JSON report to a file and
``--log`` every frame on the bus (format by suffix: .blf, .asc, .csv, ...).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from collections import Counter
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

from firmware_bridge.faults import parse_fault
from firmware_bridge.frame_log import LOG_SUFFIXES
from firmware_bridge.profiles import PROFILES
from firmware_bridge.realtime import stream_on
from firmware_bridge.session import FeedforwardSource, Rig
from firmware_bridge.settings import CanConfig, load_can_config
from gms_comp.app.signals import stop_requests
from gms_comp.arguments import (
    float_in_range,
    input_file,
    int_in_range,
    output_file,
    suffixed_file,
)
from gms_comp.atomic import atomic_path, write_text
from gms_comp.config import default_config_path
from gms_comp.errors import InputError
from gms_comp.validation import MAX_SEED

MAX_DURATION_S = 3600.0
MAX_STREAM_CYCLES = 1_000_000
"""The run keeps an audit record per cycle (about 250 B): at most this many cycles."""
EMCY_MEANINGS = {
    "0x8100": "SYNC lost",
    "0x8130": "compensator heartbeat lost",
    "0x8250": "RPDO timeout",
}


def register(subparsers: Any) -> None:
    """Add the ``stream`` subcommand to ``subparsers``."""
    p = subparsers.add_parser(
        "stream",
        help="stream the feedforward over CAN (default: to the built-in drive emulator)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("config", nargs="?", type=input_file, help="config file (default: Table 1)")
    p.add_argument("--profile", choices=tuple(PROFILES), help="override [can] profile")
    p.add_argument("--interface", help="python-can interface (virtual, socketcan, pcan, ...)")
    p.add_argument("--channel", help="python-can channel")
    p.add_argument(
        "--duration",
        type=float_in_range(0.0, MAX_DURATION_S, lo_open=True),
        default=2.0,
        metavar="S",
        help=f"seconds of streaming, 0 < S <= {MAX_DURATION_S:g} (2)",
    )
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
    p.add_argument(
        "--seed",
        type=int_in_range(0, MAX_SEED),
        default=0,
        help=f"seed of the fault injector, 0 to {MAX_SEED} (0)",
    )
    p.add_argument(
        "--json", action="store_true", help="print the report as JSON on stdout, nothing else"
    )
    p.add_argument(
        "-o", "--output", type=output_file, metavar="FILE.json", help="write the JSON report"
    )
    p.add_argument(
        "--log",
        type=suffixed_file(LOG_SUFFIXES, "frame log"),
        metavar="FILE",
        help=f"log all frames ({', '.join(LOG_SUFFIXES)})",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Stream, print the summary or JSON, write the files asked for; exit 1 if unsafe."""
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
    cycles = args.duration / cfg.cycle_period_s
    if cycles > MAX_STREAM_CYCLES:
        raise InputError(
            "--duration",
            "",
            f"{args.duration:g} s at a {cfg.cycle_period_s * 1e3:g} ms cycle is "
            f"{cycles:.3g} cycles, more than {MAX_STREAM_CYCLES:,} (an audit record each)",
        )
    faults = [parse_fault(spec) for spec in args.fault]
    _check_scenario(config_path)  # a config the observer cannot follow: refused before the bus
    with contextlib.ExitStack() as files:
        stop = files.enter_context(stop_requests())
        log = None if args.log is None else files.enter_context(atomic_path(args.log))
        # the rig opens first: another compensator on the channel is refused before the
        # work, and the claim is kept while the observer is set up
        with Rig(cfg, faults, args.seed, log, builtin_drive=not args.external_drive) as rig:
            with rig.watching():
                source = gms_observer_source(config_path, cfg, args.duration)
            with stop.deferred() as stop_request:
                report = stream_on(rig, source, args.duration, stop_request=stop_request,
                                   progress=_progress(args.duration))  # fmt: skip
    report["source"] = "gms_observer"
    text = json.dumps(report, indent=2, sort_keys=True)
    print(text if args.json else summary(report, cfg))
    written = [] if args.log is None else [args.log]
    if args.output is not None:
        written.append(write_text(args.output, text + "\n"))
    for path in written:
        print(f"wrote {path}", file=sys.stderr if args.json else sys.stdout)
    unsafe = (report["stale_or_corrupt_applied"] or 0) > 0 or (
        (report["max_applied_current_A"] or 0.0) > cfg.max_current_A + 1e-9
    )
    if report["interrupted"]:
        print(
            f"gms-comp stream: stopped by {stop.name or 'Ctrl-C'}: ramped to 0 A, session released",
            file=sys.stderr,
        )
        return stop.exit_code
    return 1 if unsafe else 0


def _progress(duration_s: float) -> Callable[[float, dict[str, Any]], None]:
    def show(time_s: float, figures: dict[str, Any]) -> None:
        print(f"stream: {time_s:.0f} s of {duration_s:g} s, {figures['frames_sent']} frames "
              "sent", file=sys.stderr, flush=True)  # fmt: skip

    return show


def summary(report: dict[str, Any], cfg: CanConfig) -> str:
    """The human summary of a stream report: what ran, the key figures, how it ended.

    Parameters
    ----------
    report
        The report of :func:`firmware_bridge.realtime.stream_on`.
    cfg
        The ``[can]`` section the stream ran with.

    Returns
    -------
    str
        A few lines, units included.
    """
    sync = report.get("sync_source")
    lines = [
        f"streamed {report['cycles']} cycles of {cfg.cycle_period_s * 1e3:g} ms to the "
        f"{report['drive']} drive ({report['profile']}"
        + (f", SYNC from the {sync}" if sync else "")
        + f", {cfg.interface} {cfg.channel}): {report['frames_sent']} frames sent, "
        f"bus load {100 * report['bus_load']:.1f} %",
        f"loop time p99 {report['loop_time_p99_s'] * 1e6:.0f} us, "
        f"{report['late_cycles']} late cycles",
    ]
    if report["faults_injected"]:
        injected = ", ".join(f"{k} {n}" for k, n in sorted(report["faults_injected"].items()))
        lines.append(f"faults injected: {injected}")
    if report["frames_applied"] is not None:
        rejected = {k: n for k, n in report["frames_rejected"].items() if n}
        why = ", ".join(f"{k} {n}" for k, n in rejected.items()) or "none"
        lines.append(
            f"drive applied {report['frames_applied']} frames, rejected {why}; "
            f"stale or corrupt applied: {report['stale_or_corrupt_applied']}; "
            f"max applied {report['max_applied_current_A']:.3f} A "
            f"(limit {cfg.max_current_A:g} A)"
        )
        emcy = Counter(report["emcy"])
        if emcy:
            codes = ", ".join(
                f"{code} {EMCY_MEANINGS.get(code, '')} x{n}".replace("  ", " ")
                for code, n in sorted(emcy.items())
            )
            lines.append(f"drive EMCY during the stream (late or missing frames): {codes}")
    if report.get("sync_lost"):
        lines.append("the NC's SYNC stopped: the stream ended silent, the drive fell back to 0 A")
    elif "end_of_stream" in report:
        lines.append(f"end: {report['end_of_stream']}")
    if report["drive_state"] is not None:
        lines.append(f"drive state at the end: {report['drive_state']}")
    if report.get("foreign_frames"):
        lines.append(f"WARNING: {report['foreign_frames']} frames of another node with our ids")
    return "\n".join(lines)


def _check_scenario(config_path: Path) -> None:
    from sim.scenarios import load_scenario  # the simulator only when streaming

    load_scenario(config_path)


def gms_observer_source(config_path: Path, cfg: CanConfig, duration_s: float) -> FeedforwardSource:
    """The GMS observer's feedforward along the config's sine, sampled at the CAN cycle."""
    from gms_comp.runtime.observer import FrictionObserver
    from sim.scenarios import load_scenario, reduced_table
    from sim.trajectories import sine

    s = load_scenario(config_path)
    c = s.scenario
    observer = FrictionObserver(
        reduced_table(s),
        s.plant.force_constant_N_per_A,
        cfg.cycle_period_s,
        s.compensator.friction_level_scale,
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
