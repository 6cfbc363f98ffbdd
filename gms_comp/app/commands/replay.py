"""``gms-comp replay``: a measured closed-loop run replayed in the simulated axis.

The record's own loop runs its reference on a rigid axis with a chosen friction model
(:mod:`gms_comp.app.replay`); the output is scored as the EMPS benchmark scores its
simulation, beside the benchmark's reference model on the same record, per motion
phase, and, with a GMS table as the model, the compensator on that axis.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from gms_comp.app import replay as rp
from gms_comp.app import replay_compensation as rc
from gms_comp.arguments import float_in_range, input_file, plot_file
from gms_comp.atomic import atomic_path
from sim.link import DirectLink, FeedforwardLink
from sim.position_loop import LoopRun

# The benchmark paper's simulation errors (§3.5) and the re-statement's q error RMS.
PUBLISHED = {
    "DATA_EMPS.mat": {"position": 0.013752, "velocity": 0.22911, "acceleration": 8.6036,
                      "force": 5.848, "position_error_rms_m": 20.5e-6},
    "DATA_EMPS_PULSES.mat": {"position": 0.0080248, "velocity": 0.47888,
                             "acceleration": 19.8152, "force": 8.9409,
                             "position_error_rms_m": 12.0e-6},
}  # fmt: skip


def register(subparsers: Any) -> None:
    """Add the ``replay`` subcommand."""
    p = subparsers.add_parser(
        "replay",
        help="replay a measured closed-loop run in the simulated axis",
        description=(
            "Run the record's own position loop (EMPS: its kp, kv, gtau, the benchmark's "
            "one-sample delay or the record's timing (--loop), "
            "+-10 V saturation, pulses) on its reference with a friction model, and compare "
            "position, velocity, acceleration and drive force with the measurement as the "
            "EMPS benchmark does, beside the benchmark's reference model. With a GMS table "
            "as the model: no feedforward, the reference model's and the GMS observer's on "
            "that axis."
        ),
    )
    p.add_argument("trace", type=input_file, metavar="TRACE", help="EMPS .mat record")
    p.add_argument(
        "--model",
        type=input_file,
        metavar="FILE",
        help=(
            "friction model: a GMS table (diagnose --table writes the extended one) or a "
            "diagnose JSON (its baseline); default: the benchmark's reference model"
        ),
    )
    p.add_argument(
        "--config",
        type=input_file,
        help='[controller] with structure = "position_velocity" for a record without gains',
    )
    p.add_argument(
        "--loop",
        choices=("record", "benchmark"),
        default="record",
        help=(
            "timing of the loop: the record's own (default), the command acting in its own "
            "cycle (the recorded command obeys the control law with no delay) through the "
            "table's drive lag less the half cycle it is held for; or the benchmark's "
            "Simulink loop, a one-sample delay before the drive and a table's drive lag "
            "left out (the paper's rows)"
        ),
    )
    p.add_argument(
        "--time-base",
        choices=("data", "simulink"),
        help=(
            "cycles at the record's samples (default with --loop record), or cycles of "
            "t[9]-t[8] from 0 as the benchmark's Simulink model (default with --loop "
            "benchmark; 0.4 ms off the record's clock by the end of DATA_EMPS)"
        ),
    )
    p.add_argument(
        "--reversal-deadband",
        type=float_in_range(0.0, rp.MAX_REVERSAL_DEADBAND_M),
        default=rp.REVERSAL_DEADBAND_M,
        metavar="M",
        help=(
            "retreat in m before a table's reversal transient starts again in the simulated "
            f"axis (default {rp.REVERSAL_DEADBAND_M:g}, chosen on DATA_EMPS)"
        ),
    )
    p.add_argument(
        "--link",
        choices=("can", "direct"),
        default="can",
        help="path of the compensators' feedforward: virtual CAN bus and drive (default)",
    )
    p.add_argument("--json", action="store_true", help="print the result as JSON on stdout")
    p.add_argument(
        "--plot",
        type=plot_file,
        metavar="PNG",
        help="plot errors and force over time (and <stem>_compensation<suffix>)",
    )
    p.set_defaults(func=run)


def _say(args: argparse.Namespace, text: str) -> None:
    print(text, file=sys.stderr if args.json else sys.stdout)


def run(args: argparse.Namespace) -> int:
    """Replay, score, compensate, report."""
    controller = None
    if args.config:
        controller = rp.parse_controller(args.config)
    if args.time_base is None:
        args.time_base = "data" if args.loop == "record" else "simulink"
    rp.load_model(args.model, args.reversal_deadband)  # a bad model is refused before the work
    record = rp.load_record(args.trace, controller, args.time_base, args.loop)
    held = record.loop.period_s if args.loop == "record" else None
    choice = rp.load_model(args.model, args.reversal_deadband, held)
    print(f"replaying {Path(args.trace).name} with the {choice.name} model ...", file=sys.stderr)
    started = time.perf_counter()
    model_run = rp.replay(record, choice.axis)
    replay_s = time.perf_counter() - started
    rp.check_finite(model_run, str(args.trace))
    reference_run = rp.replay(record, rp.reference_model())
    masks = rp.phases(record)
    doc: dict[str, Any] = {
        "trace": str(args.trace),
        "model": {"name": choice.name, "file": str(args.model) if args.model else None},
        "time_base": args.time_base,
        "loop": args.loop,
        "command_delay_cycles": record.loop.delay_cycles,
        "drive_lag_s": choice.axis.drive_lag_s,
        "samples": int(record.reference_m.size),
        "replay_s": replay_s,
        **rp.replay_scores(record, model_run),
        "reference": rp.replay_scores(record, reference_run),
        "phases": {
            "reference": rp.phase_residuals(record, reference_run, masks),
            "model": rp.phase_residuals(record, model_run, masks),
        },
    }
    published = PUBLISHED.get(Path(args.trace).name)
    if published and controller is None:
        # the paper's rows, and the reference model replayed on the paper's timing beside
        doc["published_reference"] = published
        if (args.time_base, args.loop) == ("simulink", "benchmark"):
            doc["reference_benchmark_timing"] = doc["reference"]
        else:
            paper = rp.load_record(args.trace, None, "simulink", "benchmark")
            doc["reference_benchmark_timing"] = rp.replay_scores(
                paper, rp.replay(paper, rp.reference_model())
            )
    comp = None
    if choice.table is not None:
        print(f"compensation on the {choice.name} axis ({args.link} link) ...", file=sys.stderr)
        ideal, comp = rc.compensation(record, choice.axis, choice.table, _links(record, args.link))
        doc["compensation"] = {
            "plant": choice.name,
            "link": args.link,
            "strategies": {name: scores for name, (_, scores) in comp.items()},
        }
    files = []
    if args.plot:
        files.append(_plot(record, reference_run, model_run, choice.name, masks, args.plot))
        if comp is not None:
            path = args.plot.with_name(f"{args.plot.stem}_compensation{args.plot.suffix}")
            files.append(_plot_compensation(record, ideal, comp, path))
    doc["files"] = [str(f) for f in files]
    if args.json:
        sys.stdout.write(json.dumps(doc, indent=2) + "\n")
    else:
        print(_summary(doc))
    for f in files:
        _say(args, f"wrote {f}")
    return 0


def _links(record: rp.Record, kind: str) -> Callable[[], contextlib.AbstractContextManager[Any]]:
    """Opens the feedforward path of one run: the CAN bus (its current scaled to the
    command range, 1 per mille steps) or the direct path."""

    @contextlib.contextmanager
    def direct() -> Iterator[FeedforwardLink]:
        yield DirectLink()

    if kind == "direct":
        return direct
    from firmware_bridge.link import CanFeedforwardLink
    from firmware_bridge.settings import CanConfig

    limit = record.loop.command_limit
    cfg = CanConfig(max_current_A=limit, rated_current_A=limit)
    return lambda: CanFeedforwardLink(cfg, servo_period_s=record.loop.period_s)


# --- the human summary ----------------------------------------------------------------------


def _row(name: str, scores: Mapping[str, Any]) -> str:
    rel = scores.get("relative_error_pct", scores)
    cells = [f"{rel[k]:>10.4g}" for k in ("position", "velocity", "acceleration", "force")]
    return f"{name:<20}" + "".join(cells) + f"{scores['position_error_rms_m'] * 1e6:>12.2f}"


def _summary(doc: Mapping[str, Any]) -> str:
    lines = [
        f"replayed {doc['trace']} ({doc['samples']} cycles, {doc['time_base']} time base, "
        f"{doc['loop']} loop: command delay {doc['command_delay_cycles']} cycle(s), drive lag "
        f"{doc['drive_lag_s'] * 1e3:.3g} ms) in {doc['replay_s']:.2f} s; relative errors % "
        "and position error RMS:",
        f"{'model':<20}{'position':>10}{'velocity':>10}{'accel.':>10}{'force':>10}{'q RMS um':>12}",
    ]
    if "published_reference" in doc:
        lines.append("on the benchmark's Simulink timing (one-sample delay, t[9]-t[8] cycles):")
        lines.append(_row("  reference (paper)", doc["published_reference"]))
        lines.append(_row("  reference (ours)", doc["reference_benchmark_timing"]))
        lines.append(f"on this replay's timing ({doc['loop']} loop, {doc['time_base']} time base):")
    lines.append(_row("  reference", doc["reference"]))
    if doc["model"]["name"] != "reference":
        lines.append(_row(f"  {doc['model']['name']}", doc))
    ref, model = doc["phases"]["reference"], doc["phases"]["model"]
    lines += ["", "residual by motion phase (force RMS N, position error RMS um):"]
    lines.append(f"{'phase':<20}{'share':>7}{'F ref':>9}{'F model':>9}{'q ref':>8}{'q model':>9}")
    for name, r in ref.items():
        m = model[name]
        lines.append(
            f"{name:<20}{r['fraction']:>7.1%}{r['force_error_rms_N']:>9.2f}"
            f"{m['force_error_rms_N']:>9.2f}{r['position_error_rms_m'] * 1e6:>8.1f}"
            f"{m['position_error_rms_m'] * 1e6:>9.1f}"
        )
    if "compensation" in doc:
        comp = doc["compensation"]
        lines += [
            "",
            f"compensation on the {comp['plant']} axis, feedforward over the {comp['link']} "
            "link (um; friction share = frictionless axis minus this one):",
            f"{'feedforward':<12}{'RMS':>9}{'peak':>9}{'reversal':>10}"
            f"{'fric RMS':>10}{'fric peak':>11}{'fric rev.':>11}",
        ]
        for name, s in comp["strategies"].items():
            keys = ("rms_following_error_m", "peak_following_error_m",
                    "peak_reversal_following_error_m", "rms_friction_error_m",
                    "peak_friction_error_m", "peak_reversal_friction_error_m")  # fmt: skip
            widths = (9, 9, 10, 10, 11, 11)
            lines.append(
                f"{name:<12}"
                + "".join(f"{s[k] * 1e6:>{w}.1f}" for k, w in zip(keys, widths, strict=True))
            )
    return "\n".join(lines)


# --- plots ----------------------------------------------------------------------------------

PHASE_COLOURS = {
    "reversal": "tab:red",
    "standstill": "0.5",
    "constant_speed_pos": "tab:green",
    "constant_speed_neg": "tab:blue",
    "acceleration": "tab:orange",
}
PHASE_LABELS = {
    "reversal": "reversal (+-25 ms)",
    "standstill": "standstill",
    "constant_speed_pos": "constant speed, +",
    "constant_speed_neg": "constant speed, -",
    "acceleration": "acceleration",
}


def _plot(
    record: rp.Record,
    reference_run: LoopRun,
    model_run: LoopRun,
    model_name: str,
    masks: Mapping[str, np.ndarray],
    path: Path,
) -> Path:
    """Position error (reference minus position) and drive force over time, measured on
    top of the simulations, motion phases shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = record.time_s - record.time_s[0]
    gain = record.loop.drive_gain_N
    fig, (ax_q, ax_d, ax_f) = plt.subplots(3, 1, figsize=(11, 9), sharex=True)
    sims = [("reference model", reference_run, "tab:purple")]
    if model_name != "reference":
        sims.append((f"{model_name} model", model_run, "tab:cyan"))
    for label, r, colour in sims:
        ax_q.plot(t, (record.reference_m - r.position_m) * 1e6, color=colour, lw=0.8, label=label)
        ax_d.plot(t, (record.position_m - r.position_m) * 1e6, color=colour, lw=0.8, label=label)
        ax_f.plot(t, gain * r.command, color=colour, lw=0.8, label=label)
    ax_q.plot(t, (record.reference_m - record.position_m) * 1e6, "k", lw=0.7, label="measured")
    ax_f.plot(t, record.force_N, "k", lw=0.7, label="measured")
    for ax in (ax_q, ax_d, ax_f):
        for name, mask in masks.items():
            ax.fill_between(
                t, 0, 1, where=mask, transform=ax.get_xaxis_transform(),
                color=PHASE_COLOURS[name], alpha=0.15, lw=0, label=PHASE_LABELS[name],
            )  # fmt: skip
    ax_q.set_ylabel("qg - q [µm]")
    ax_q.set_title(f"{Path(record.source).name}: following error, measured and replayed")
    ax_d.set_ylabel("q measured - q simulated [µm]")
    ax_d.set_title("replay's position error (output error)")
    ax_f.set_ylabel("drive force [N]")
    ax_f.set_xlabel("time [s]")
    ax_f.set_title("drive force (drive gain x command), measured and replayed")
    ax_q.legend(loc="upper right", fontsize=7, ncol=4)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
    return path


def _plot_compensation(
    record: rp.Record,
    ideal: LoopRun,
    comp: Mapping[str, tuple[LoopRun, Mapping[str, float]]],
    path: Path,
) -> Path:
    """Following error per feedforward over the run, and its friction share (the
    frictionless axis's position minus this one's) around the first reversal."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.arange(record.reference_m.size) * record.loop.period_s
    turns = rc.reference_reversals(record)
    fig, (ax_all, ax_zoom) = plt.subplots(1, 2, figsize=(12, 4.5))
    first = int(turns[0]) if turns.size else 0
    zoom = slice(max(0, first - 50), first + 200)
    labels = {
        "none": "no feedforward",
        "reference": "reference model (Coulomb + viscous)",
        "gms": "GMS observer",
    }
    for name, (r, _) in comp.items():
        label = labels.get(name, name)
        ax_all.plot(t, (record.reference_m - r.position_m) * 1e6, lw=0.7, label=label)
        share_um = (ideal.position_m - r.position_m)[zoom] * 1e6
        ax_zoom.plot((t[zoom] - t[first]) * 1e3, share_um, lw=1.0, label=label)
    ax_all.set_xlabel("time [s]")
    ax_all.set_ylabel("following error [µm]")
    ax_all.set_title("following error with each feedforward")
    ax_zoom.axvline(0.0, color="0.6", lw=0.8)
    ax_zoom.set_xlabel("time from the first reversal [ms]")
    ax_zoom.set_ylabel("friction share of the following error [µm]")
    ax_zoom.set_title("friction's share at the first reversal")
    ax_all.legend(fontsize=8)
    ax_zoom.legend(fontsize=8)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
    return path
