"""``gms-comp simulate``: one scenario of the simulated axis under every strategy.

With ``--via-can`` the feedforward travels over the virtual CAN bus to the
drive emulator (the ``[can]`` section) instead of the direct path. One frame
goes per CAN cycle (``can.cycle_period_s``) and the drive holds the applied
value until the next, so with no faults the run equals the direct path with
no transport delay of its own (profile ``cia402`` as SYNC master applies the
frame in the cycle it is sent; with ``sync_master = false`` one CAN cycle
later), a hold of ``cycle_period_s / servo_period_s`` servo cycles, and the
current quantized to the frame's step (``cia402``: 1 per mille of
``rated_current_A``; ``e2e``: the DBC's scale), saturated at
``can.max_current_A``. ``scenario.transport_delay_cycles`` is not added: the
bus is the transport. tests/test_sim_via_can.py checks that equivalence.

A two-axis circle (``[scenario] circle_axis = "xy"``) runs both axes, each on its
own plant, controller, truth and compensator; the per-strategy scores stay those
of the x axis, and ``strategies.<name>.circularity`` scores the contour (radial
error); ``--plot`` then also writes ``<PNG stem>_circularity<suffix>``, the polar
plot of the radial error.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from gms_comp.arguments import input_file, output_file, plot_file
from gms_comp.atomic import atomic_path, write_text
from gms_comp.errors import ScenarioError
from sim.closed_loop import RunResult
from sim.link import DirectLink, FeedforwardLink
from sim.scenarios import (
    Physics,
    Scenario,
    axis_scenarios,
    circularity,
    load_scenario,
    radial_error,
    reduced_table,
    run_strategies,
    score,
)
from sim.trajectories import reversals


def register(subparsers: Any) -> None:
    """Add the ``simulate`` subcommand to ``subparsers``."""
    parser = subparsers.add_parser(
        "simulate",
        help="run the simulated linear-motor axis under each friction compensation",
        description=(
            "Closed-loop simulation of a linear-motor axis whose friction is the transient "
            "ball model, with no compensation, Coulomb+viscous, LuGre and GMS feedforward. "
            "Without CONFIG: the default scenario on the packaged Table 1 physics."
        ),
    )
    parser.add_argument("config", nargs="?", type=input_file, help="config TOML (default: Table 1)")
    parser.add_argument(
        "--json", action="store_true", help="print the scores as JSON on stdout (nothing else)"
    )
    parser.add_argument(
        "-o", "--output", type=output_file, metavar="FILE", help="write the scores as JSON"
    )
    parser.add_argument(
        "--plot",
        type=plot_file,
        metavar="PNG",
        help=(
            "plot the following error around a reversal (a two-axis circle also writes "
            "<stem>_circularity<suffix>, the polar plot of the radial error)"
        ),
    )
    parser.add_argument(
        "--via-can",
        action="store_true",
        help=(
            "carry the feedforward over the virtual CAN bus and drive emulator ([can] "
            "section); without faults this equals the direct path with the CAN cycle's "
            "hold and no extra delay, to within the frame's quantization"
        ),
    )
    parser.set_defaults(func=run)


@contextlib.contextmanager
def _links(
    s: Scenario, via_can: bool, can_report: dict[str, Any]
) -> Iterator[Callable[[int], FeedforwardLink]]:
    """Link factory for the runs: direct (with the configured delay) or over CAN; over CAN,
    ``can_report`` gets the frames of every link, summed, before the buses close."""
    if not via_can:
        yield DirectLink
        return
    from firmware_bridge.link import CanFeedforwardLink
    from firmware_bridge.settings import load_can_config

    cfg = load_can_config(s.path)
    links: list[CanFeedforwardLink] = []
    with contextlib.ExitStack() as stack:

        def open_link(_delay_cycles: int) -> FeedforwardLink:
            # The bus brings its own transport delay; the configured one is not added.
            # One frame per CAN cycle, held by the drive over the servo cycles between.
            link = CanFeedforwardLink(cfg, servo_period_s=s.controller.servo_period_s)
            links.append(stack.enter_context(link))
            return link

        yield open_link
        can_report.update(_can_totals([link.report() for link in links], cfg.profile))


def run(args: argparse.Namespace) -> int:
    """Run every strategy on every axis of the scenario; report and write."""
    s = load_scenario(args.config)
    table = reduced_table(s)  # made or read once, and a table that does not fit refused now
    physics = Physics(table=lambda _s: table)
    axes = axis_scenarios(s)
    started = time.perf_counter()

    def progress(axis: str) -> Callable[[str], None]:
        def note(name: str) -> None:
            print(f"simulating {axis}{name} ...", file=sys.stderr, flush=True)

        return note

    can_report: dict[str, Any] = {}
    with _links(s, args.via_can, can_report) as link:
        runs = [
            run_strategies(
                axis,
                physics=physics,
                link=link,
                progress=progress(f"{axis.scenario.circle_axis} axis, " * (len(axes) > 1)),
            )
            for axis in axes
        ]
    elapsed_s = time.perf_counter() - started
    results = runs[0]
    scores = {name: score(r, s.scenario) for name, r in results.items()}
    strategies: dict[str, dict[str, Any]] = {name: dict(sc) for name, sc in scores.items()}
    contour = _contours(runs, s)
    for name, circ in contour.items():
        strategies[name]["circularity"] = circ
    duration_s = next(iter(results.values())).reference.duration_s
    simulated_s = sum(r.reference.duration_s for axis in runs for r in axis.values())
    report = {
        "config": s.path,
        "scenario": {
            "trajectory": s.scenario.trajectory,
            "axes": len(runs),
            "duration_s": duration_s,
            "servo_rate_Hz": s.controller.servo_rate_Hz,
            "transport_delay_cycles": s.scenario.transport_delay_cycles,
            "via_can": bool(args.via_can),
        },
        "strategies": strategies,
        **({"can": can_report} if can_report else {}),
        "gms_peak_reversal_reduction": _reductions(scores),
        "simulated_s": simulated_s,
        "elapsed_s": elapsed_s,
        "realtime_factor": simulated_s / elapsed_s,
    }
    files: list[Path] = []
    if args.output:
        files.append(write_text(args.output, json.dumps(report, indent=2) + "\n"))
    if args.plot:
        files.append(_plot(results, s, args.plot))
        if contour:
            circ = args.plot.with_name(f"{args.plot.stem}_circularity{args.plot.suffix}")
            files.append(_plot_circularity(runs, s, circ))
    if args.json:
        sys.stdout.write(json.dumps(report, indent=2) + "\n")
    else:
        print(_what(report, len(results)))
        if can_report:
            print(_can_line(can_report))
        print(_table(scores))
        if contour:
            print(_circularity_table(contour))
    for f in files:
        print(f"wrote {f}", file=sys.stderr if args.json else sys.stdout)
    return 0


def _what(report: dict[str, Any], strategies: int) -> str:
    """What was simulated, and how fast."""
    sc = report["scenario"]
    axes = f" x {sc['axes']} axes" if sc["axes"] > 1 else ""
    path = "over the virtual CAN bus" if sc["via_can"] else (
        f"direct path, {sc['transport_delay_cycles']} cycle(s) delay"
    )  # fmt: skip
    return (
        f"simulated {sc['trajectory']} ({sc['duration_s']:.3g} s at {sc['servo_rate_Hz']:g} Hz, "
        f"{path}): {strategies} strategies{axes} x {sc['duration_s']:.3g} s = "
        f"{report['simulated_s']:.3g} s of axis time in {report['elapsed_s']:.3g} s "
        f"({_factor(report['realtime_factor'])} real time, set-up included)"
    )


def _can_totals(reports: list[dict[str, Any]], profile: str) -> dict[str, Any]:
    """The CAN figures of all links of a run, summed."""
    rejected: dict[str, int] = {}
    for r in reports:
        for reason, n in r["frames_rejected"].items():
            rejected[reason] = rejected.get(reason, 0) + n
    return {
        "profile": profile,
        "links": len(reports),
        "frames_sent": sum(r["frames_sent"] for r in reports),
        "frames_applied": sum(r["frames_applied"] for r in reports),
        "frames_rejected": rejected,
        "stale_or_corrupt_applied": sum(r["stale_or_corrupt_applied"] for r in reports),
        "max_applied_current_A": max((r["max_applied_current_A"] for r in reports), default=0.0),
    }


def _can_line(can: dict[str, Any]) -> str:
    """One line of CAN figures for the summary."""
    refused = sum(can["frames_rejected"].values())
    return (
        f"CAN ({can['profile']}, {can['links']} links): {can['frames_sent']} frames sent, "
        f"{can['frames_applied']} applied, {refused} refused, stale or corrupt applied: "
        f"{can['stale_or_corrupt_applied']}, max {can['max_applied_current_A']:.3f} A"
    )


def _factor(value: float) -> str:
    """A real-time factor with the digits it needs (never "0x")."""
    return f"{value:.2g}x" if value < 10 else f"{value:.0f}x"


def _contours(runs: list[dict[str, RunResult]], s: Scenario) -> dict[str, dict[str, float | None]]:
    """Circularity scores per strategy of a two-axis run (empty for one axis)."""
    if len(runs) != 2:
        return {}
    x, y = runs
    return {name: circularity(x[name], y[name], s.scenario) for name in x}


def _reductions(scores: dict[str, dict[str, float | None]]) -> dict[str, float | None]:
    """How many times smaller the GMS peak reversal error is than each other strategy's."""
    gms = scores.get("gms", {}).get("peak_reversal_error_m")
    out: dict[str, float | None] = {}
    for name, sc in scores.items():
        other = sc["peak_reversal_error_m"]
        if name != "gms":
            out[f"vs_{name}"] = other / gms if other is not None and gms else None
    return out


def _table(scores: dict[str, dict[str, float | None]]) -> str:
    """Scores in nanometres, one strategy per line."""
    lines = [f"{'strategy':<16}{'peak reversal nm':>18}{'rms nm':>10}{'peak stop nm':>14}"]
    for name, sc in scores.items():
        lines.append(
            f"{name:<16}{_nm(sc['peak_reversal_error_m']):>18}{_nm(sc['rms_error_m']):>10}"
            f"{_nm(sc['peak_stop_error_m']):>14}"
        )
    return "\n".join(lines)


def _nm(value: float | None) -> str:
    """A length in nanometres for the tables, ``-`` for none."""
    return "-" if value is None else f"{value * 1e9:.1f}"


def _circularity_table(contour: dict[str, dict[str, float | None]]) -> str:
    """Contour scores in nanometres, one strategy per line."""
    lines = [f"{'circularity':<16}{'peak quadrant nm':>18}{'rms radial nm':>15}"]
    for name, circ in contour.items():
        peak, rms = circ["peak_quadrant_error_m"], circ["rms_radial_error_m"]
        lines.append(f"{name:<16}{_nm(peak):>18}{_nm(rms):>15}")
    return "\n".join(lines)


def _plot_circularity(runs: list[dict[str, RunResult]], s: Scenario, path: Path) -> Path:
    """The classic circularity plot: radial error against the angle on the circle,
    magnified about a zero-error circle (the polar origin sits below zero)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.projections.polar import PolarAxes

    x, y = runs
    radius_m = s.scenario.radius_m
    fig, ax = plt.subplots(figsize=(6, 6), subplot_kw={"projection": "polar"})
    assert isinstance(ax, PolarAxes)
    span_nm = 0.0
    labels = {"none": "no compensation", "gms": "GMS feedforward"}
    for name, rx in x.items():
        ry = y[name]
        angle = np.arctan2(ry.reference.position_m - radius_m, rx.reference.position_m)
        radial_nm = radial_error(rx, ry, radius_m) * 1e9
        span_nm = max(span_nm, float(np.max(np.abs(radial_nm))))
        ax.plot(
            angle, radial_nm, label=labels.get(name, f"{name} feedforward"),
            lw=1.6 if name == "gms" else 0.9, zorder=3 if name == "gms" else 2,
        )  # fmt: skip
    # Zero error is drawn as a circle of radius 2 span, the errors (+-span) around it:
    # nanometres magnified to a visible fraction of the circle.
    ax.plot(np.linspace(0, 2 * np.pi, 361), np.zeros(361), "k--", lw=0.8, label="commanded")
    ax.set_rorigin(-2 * span_nm)
    ax.set_rlim(-span_nm, span_nm)
    ax.set_rlabel_position(22.5)
    ax.set_title(
        f"circularity, {radius_m * 1e3:g} mm circle at {s.scenario.feed_m_s * 60:g} m/min\n"
        "radial error [nm], magnified about the commanded circle (dashed)",
        fontsize=10,
    )
    ax.legend(loc="lower left", fontsize=8, bbox_to_anchor=(-0.1, -0.1))
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120)
    plt.close(fig)
    return path


def _plot(results: dict[str, RunResult], s: Scenario, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    first = next(iter(results.values())).reference
    turns = reversals(first)
    if turns.size == 0:
        raise ScenarioError(f"{s.path}: the trajectory has no reversal to plot")
    window = round(s.scenario.reversal_window_s / first.period_s)
    lo, hi = max(0, int(turns[0]) - window // 2), min(first.cycles, int(turns[0]) + window)
    t_ms = (first.time_s[lo:hi] - first.time_s[turns[0]]) * 1e3
    fig, ax = plt.subplots(figsize=(7, 4))
    for name, r in results.items():
        ax.plot(t_ms, r.error_m[lo:hi] * 1e6, label=name)
    ax.axvline(0.0, color="0.6", lw=0.8)
    ax.set_xlabel("time from the reversal [ms]")
    ax.set_ylabel("following error [µm]")
    ax.set_title(f"{s.scenario.trajectory}: following error at the first reversal")
    ax.legend()
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120)
    plt.close(fig)
    return path
