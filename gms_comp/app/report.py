"""The diagnosis report: one self-contained HTML file per trace (its plots embedded), and an
overview page for a fleet.

A trace's page holds what a person needs to trust or question the answer: the trace's
name, the date, the gms-comp version and the config, the verdict and every caveat, each
kept effect with its 95 % intervals, the held-out error before and after (and the
validation trace's, or the EMPS benchmark's cross-test, when there is one), what the trace
rules out (its detection limits), the residual by motion phase, and plots: the residual
against time, position and velocity, the measured and model forces, and zoomed views at a
reversal and at a break-away after a standstill, where the effects live.
"""

from __future__ import annotations

import base64
import datetime
import html
import io
from collections.abc import Mapping, Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from gms_comp.arrays import FloatArray
from gms_comp.atomic import write_text
from gms_comp.measured.diagnosis.phases import phase_label
from gms_comp.measured.diagnosis.result import Diagnosis, parameter_text

STYLE = (
    "body{font-family:sans-serif;max-width:1040px;margin:auto}"
    "table{border-collapse:collapse}td,th{border:1px solid #aaa;padding:3px 8px}"
    "img{max-width:100%}.caveat{background:#fff4d6;padding:4px 8px}"
)
# A zoomed view spans this much time around its event.
ZOOM_S = 0.15


def write_report(diagnosis: Diagnosis, doc: Mapping[str, Any], folder: str | Path) -> list[Path]:
    """Write ``index.html`` (self-contained: plots embedded) into ``folder``; return its
    path in a list. ``doc``: the diagnosis JSON as the command gives it (its trace name,
    config and any cross-test)."""
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    figures = [_residuals(diagnosis), _phases(diagnosis), _forces(diagnosis)]
    figures += [f for f in (_zoom(diagnosis, "reversal"), _zoom(diagnosis, "break-away")) if f]
    images = [_embedded(f) for f in figures]
    return [write_text(out / "index.html", _page(diagnosis, doc, images))]


def write_overview(summary: Mapping[str, Any], folder: str | Path, names: Sequence[str]) -> Path:
    """A fleet's overview page in ``folder``: a row per trace (``names``: its report
    folder) with its verdict, gain and caveats, linked to its own page, and the effects
    that recur across the fleet."""
    e = html.escape
    rows = []
    for row, name in zip(summary["traces"], names, strict=True):
        link = f'<a href="{e(name)}/index.html">{e(Path(row["trace"]).name)}</a>'
        if row.get("status") != "ok":
            rows.append(
                f"<tr><td>{link}</td><td>error</td><td></td><td>{e(str(row.get('error')))}</td></tr>"
            )
            continue
        caveats = "; ".join(c["kind"] for c in row.get("caveats", ()))
        rows.append(
            f"<tr><td>{link}</td><td>{e(row['effect'])}</td><td>{row['gain']:.1%}</td>"
            f"<td>{e(caveats)}</td></tr>"
        )
    recurring = "".join(
        f"<li>{e(r['effect'])}: {r['count']} traces ({r['share']:.0%}), median gain "
        f"{r['median_gain']:.1%}</li>"
        for r in summary["recurring_effects"]
    )
    body = (
        f"<h1>Fleet diagnosis: {len(names)} traces</h1>{_stamp()}"
        "<table><tr><th>trace</th><th>cause</th><th>gain</th><th>caveats</th></tr>"
        + "".join(rows)
        + "</table><h2>Recurring effects</h2><ul>"
        + (recurring or "<li>none</li>")
        + "</ul>"
    )
    return write_text(Path(folder) / "index.html", _html("gms-comp fleet diagnosis", body))


def _page(d: Diagnosis, doc: Mapping[str, Any], images: Sequence[str]) -> str:
    e = html.escape
    trace = str(doc.get("trace", ""))
    effects = "".join(
        f"<tr><td>{i + 1}</td><td>{e(entry['effect'])}</td><td>"
        + e(", ".join(parameter_text(k, v) for k, v in entry["parameters"].items()))
        + f"</td><td>{e(_intervals(entry))}</td><td>{entry['heldout_rms_N']:.4g}</td></tr>"
        for i, entry in enumerate(doc["effects"])
    )
    phases = "".join(
        f"<tr><td>{e(phase_label(k))}</td><td>{v['rms_N']:.4g}</td><td>{v['mean_N']:+.4g}</td>"
        f"<td>{v['fraction']:.1%}</td></tr>"
        for k, v in d.phases.items()
    )
    limits = "".join(
        f"<tr><td>{e(name)}</td><td>"
        + e(", ".join(parameter_text(k, v) for k, v in figures.items() if k != "reach"))
        + f"</td><td>{e(doc.get('to_see_smaller', {}).get(name, ''))}</td></tr>"
        for name, figures in doc.get("detection_limits", {}).items()
    )
    caveats = "".join(
        f'<p class="caveat"><b>Caveat:</b> {e(c["text"])}.</p>' for c in doc["caveats"]
    )
    structure = e(d.structure.description()) or "noise-like"
    config = e(str(doc.get("config") or "defaults"))
    inputs = "".join(f"<li>{e(k)}: {e(str(v))}</li>" for k, v in doc.get("inputs", {}).items())
    plots = "".join(f'<p><img src="{src}" alt="plot {i + 1}"></p>' for i, src in enumerate(images))
    body = f"""<h1>Diagnosis of {e(Path(trace).name or "a trace")}: {e(d.effect)}</h1>
{_stamp()}<p>Trace <code>{e(trace)}</code>; config: {config}; {d.seconds:.1f} s.</p>
<ul>{inputs}</ul>
<p>Gain {d.gain:.1%}: held-out force RMS {d.baseline_rms_N:.4g} N (baseline) to
{d.extended_rms_N:.4g} N (extended); noise {d.noise_rms_N:.3g} N. Residual left by the
extended model: {structure}.</p>{_cross_test(doc)}{caveats}
<h2>Effects kept (ranked), with 95 % intervals</h2>
<table><tr><th>#</th><th>effect</th><th>parameters</th><th>95 % intervals</th>
<th>held-out RMS [N]</th></tr>{effects or '<tr><td colspan="5">none</td></tr>'}</table>
<h2>What this trace rules out</h2>
<p>The smallest effect of each kind this trace would have revealed (none smaller is ruled out):</p>
<table><tr><th>effect</th><th>smallest revealed</th><th>to see smaller, record</th></tr>
{limits}</table>
<h2>Baseline residual by motion phase</h2>
<table><tr><th>phase</th><th>RMS [N]</th><th>mean [N]</th><th>samples</th></tr>{phases}</table>
<h2>Plots</h2>{plots}"""
    return _html(f"gms-comp diagnosis of {Path(trace).name}", body)


def _html(title: str, body: str) -> str:
    return (
        f'<!DOCTYPE html>\n<html><head><meta charset="utf-8"><title>{html.escape(title)}</title>'
        f"<style>{STYLE}</style></head><body>\n{body}\n</body></html>\n"
    )


def _stamp() -> str:
    """The date and the gms-comp version."""
    try:
        version = metadata.version("gms-comp")
    except metadata.PackageNotFoundError:
        version = "unknown"
    now = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    return f"<p>{now}, gms-comp {html.escape(version)}.</p>"


def _intervals(entry: Mapping[str, Any]) -> str:
    bounded = set(entry.get("interval_at_bound", ()))
    return ", ".join(
        f"{name} {lo:.4g} to {hi:.4g}" + (" (reaches its bound)" if name in bounded else "")
        for name, (lo, hi) in entry.get("intervals_95", {}).items()
    )


def _cross_test(doc: Mapping[str, Any]) -> str:
    """The EMPS benchmark's train and cross-test errors, when the trace has them."""
    rows = []
    for label, key in (
        ("train", "relative_error_pct"),
        ("cross-test", "validation_relative_error_pct"),
    ):
        pct = doc.get(key)
        if pct:
            rows.append(
                f"<tr><td>{label}</td><td>{pct['extended']:.2f} %</td><td>{pct['baseline']:.2f} %"
                f"</td><td>{pct['reference_idim_ls']:.2f} %</td></tr>"
            )
    if not rows:
        return ""
    return (
        "<h2>Cross-test (the EMPS benchmark's relative error)</h2><table><tr><th></th><th>extended"
        "</th><th>baseline</th><th>IDIM-LS</th></tr>" + "".join(rows) + "</table>"
    )


def _embedded(fig: Figure) -> str:
    """The figure as a PNG data URI."""
    buffer = io.BytesIO()
    fig.savefig(buffer, dpi=90, format="png")
    plt.close(fig)
    return "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


def _residuals(d: Diagnosis) -> Figure:
    s = d.series
    base, ext = s["force_N"] - s["baseline_N"], s["force_N"] - s["extended_N"]
    fig, axes = plt.subplots(3, 1, figsize=(10, 9))
    for ax, key, label, scale in zip(
        axes,
        ("time_s", "position_m", "velocity_m_s"),
        ("time [s]", "position [mm]", "velocity [mm/s]"),
        (1.0, 1e3, 1e3),
        strict=True,
    ):
        ax.plot(s[key] * scale, base, ",", color="tab:red")
        ax.plot(s[key] * scale, ext, ",", color="tab:blue")
        ax.set_xlabel(label)
        ax.set_ylabel("measured - model [N]")
    keys = [
        Line2D([], [], marker="o", ls="", color=c, label=n)
        for c, n in (("tab:red", "baseline model"), ("tab:blue", "extended model"))
    ]
    axes[0].legend(handles=keys, loc="upper right")
    fig.suptitle(f"Force residual: cause {d.effect}, gain {d.gain:.1%}")
    fig.tight_layout()
    return fig


def _phases(d: Diagnosis) -> Figure:
    fig, ax = plt.subplots(figsize=(10, 0.45 * len(d.phases) + 1.5))
    names = list(d.phases)
    ax.barh([phase_label(n) for n in names], [d.phases[n]["rms_N"] for n in names])
    ax.axvline(d.noise_rms_N, color="k", ls="--", lw=1, label="noise")
    ax.invert_yaxis()
    ax.set_xlabel("baseline residual RMS [N]")
    ax.set_title("Where the baseline model is wrong, by motion phase")
    ax.legend()
    fig.tight_layout()
    return fig


def _forces(d: Diagnosis, rows: slice = slice(None)) -> Figure:
    s = d.series
    fig, ax = plt.subplots(figsize=(10, 4))
    t = s["time_s"][rows]
    ax.plot(t, s["baseline_N"][rows], lw=0.8, color="tab:red", label="baseline model")
    ax.plot(t, s["extended_N"][rows], lw=0.8, color="tab:blue", label="extended model")
    ax.plot(t, s["force_N"][rows], lw=0.6, color="k", alpha=0.8, label="measured", zorder=3)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("force [N]")
    ax.set_title("Measured force (on top) and the models")
    ax.legend(loc="upper right")
    fig.tight_layout()
    return fig


def _zoom(d: Diagnosis, event: str) -> Figure | None:
    """The forces around the reversal (or the break-away after a standstill) where the
    extended model's residual is largest; None where the trace has none."""
    s = d.series
    at = _events(s["velocity_m_s"], event)
    if event == "break-away":  # a start the same way as before the rest, where there is one
        same_way = np.setdiff1d(at, _events(s["velocity_m_s"], "reversal"))
        at = same_way if same_way.size else at
    if at.size == 0:
        return None
    residual = np.abs(s["force_N"] - s["extended_N"]) + np.abs(s["force_N"] - s["baseline_N"])
    t = s["time_s"]
    worst = max(at, key=lambda i: float(residual[max(i - 5, 0) : i + 50].max(initial=0.0)))
    rows = slice(
        int(np.searchsorted(t, t[worst] - ZOOM_S / 3)), int(np.searchsorted(t, t[worst] + ZOOM_S))
    )
    fig = _forces(d, rows)
    fig.axes[0].set_title(f"At a {event} (t = {t[worst]:.3g} s): measured force and the models")
    return fig


def _events(velocity: FloatArray, event: str) -> FloatArray:
    """Sample indices of the reversals (the speed's sign turns) or of the break-aways (the
    first motion after a standstill of at least 20 samples)."""
    moving = np.abs(velocity) > 0.01 * float(np.max(np.abs(velocity)))
    if event == "reversal":
        sign = np.sign(velocity) * moving
        signs = sign[moving]
        rows = np.flatnonzero(moving)
        return rows[1:][signs[1:] != signs[:-1]]
    starts = np.flatnonzero(moving[1:] & ~moving[:-1]) + 1
    still = np.concatenate([[0], np.cumsum(~moving)])
    return np.array(
        [i for i in starts if i >= 20 and still[i] - still[i - 20] == 20], dtype=np.int64
    )
