"""The report of a diagnosis: plots (residual against time, position, velocity; residual
by phase; measured and model force) and an index.html with the plots and the table."""

from __future__ import annotations

import html
from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from gms_comp.atomic import atomic_path, write_text
from gms_comp.measured.diagnosis.phases import phase_label
from gms_comp.measured.diagnosis.result import Diagnosis, parameter_text

__all__ = ["parameter_text", "phase_label", "write_report"]


def _save(fig: Figure, path: Path, source: str) -> Path:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=100, format="png", metadata={"Source": source})
    plt.close(fig)
    return path


def write_report(
    diagnosis: Diagnosis, folder: str | Path, inputs: Mapping[str, str] | None = None
) -> list[Path]:
    """Write the report's PNG files and index.html into ``folder``; return their paths.

    ``inputs`` (what each input of the run was: ``{"trace": "t.csv (sha256 ...)"}``) is
    named in the page and in each PNG's ``Source`` text."""
    named = dict(inputs or {})
    source = "; ".join(f"{k}: {v}" for k, v in named.items())
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    s = diagnosis.series
    base = s["force_N"] - s["baseline_N"]
    ext = s["force_N"] - s["extended_N"]
    paths = []
    fig, axes = plt.subplots(3, 1, figsize=(10, 9))
    for ax, key, label, scale in zip(
        axes, ("time_s", "position_m", "velocity_m_s"),
        ("time [s]", "position [mm]", "velocity [mm/s]"), (1.0, 1e3, 1e3), strict=True,
    ):  # fmt: skip
        ax.plot(s[key] * scale, base, ",", color="tab:red", label="baseline model")
        ax.plot(s[key] * scale, ext, ",", color="tab:blue", label="extended model")
        ax.set_xlabel(label)
        ax.set_ylabel("measured - model [N]")
    # pixel markers do not scale in a legend: its keys are drawn as dots
    keys = [
        Line2D([], [], marker="o", ls="", color=c, label=n)
        for c, n in (("tab:red", "baseline model"), ("tab:blue", "extended model"))
    ]
    axes[0].legend(handles=keys, loc="upper right")
    fig.suptitle(
        f"Force residual: cause {diagnosis.effect}, gain {diagnosis.gain:.1%} (held-out RMS "
        f"{diagnosis.baseline_rms_N:.3g} N -> {diagnosis.extended_rms_N:.3g} N)"
    )
    fig.tight_layout()
    paths.append(_save(fig, out / "residual.png", source))

    fig, ax = plt.subplots(figsize=(10, 0.45 * len(diagnosis.phases) + 1.5))
    names = list(diagnosis.phases)
    ax.barh([phase_label(n) for n in names], [diagnosis.phases[n]["rms_N"] for n in names])
    ax.axvline(diagnosis.noise_rms_N, color="k", ls="--", lw=1, label="noise")
    ax.invert_yaxis()
    ax.set_xlabel("baseline residual RMS [N]")
    ax.set_title("Where the baseline model is wrong, by motion phase")
    ax.legend()
    fig.tight_layout()
    paths.append(_save(fig, out / "phases.png", source))

    fig, ax = plt.subplots(figsize=(10, 4))
    ax.plot(s["time_s"], s["baseline_N"], lw=0.6, color="tab:red", label="baseline model")
    ax.plot(s["time_s"], s["extended_N"], lw=0.6, color="tab:blue", label="extended model")
    ax.plot(s["time_s"], s["force_N"], lw=0.6, color="k", alpha=0.8, label="measured", zorder=3)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("force [N]")
    ax.set_title("Measured force (on top) and the models")
    ax.legend(loc="upper right")
    fig.tight_layout()
    paths.append(_save(fig, out / "force.png", source))
    paths.append(write_text(out / "index.html", _html(diagnosis, [p.name for p in paths], named)))
    return paths


def _html(d: Diagnosis, images: list[str], inputs: Mapping[str, str]) -> str:
    e = html.escape
    sources = "".join(f"<li>{e(k)}: {e(v)}</li>" for k, v in inputs.items())
    rows = "".join(
        f"<tr><td>{i + 1}</td><td>{e(c.effect.name)}</td><td>"
        + e(", ".join(parameter_text(k, v) for k, v in c.effect.parameters().items()))
        + f"</td><td>{c.heldout_rms_N:.4g}</td></tr>"
        for i, c in enumerate(d.ranked)
    )
    phases = "".join(
        f"<tr><td>{e(phase_label(k))}</td><td>{v['rms_N']:.4g}</td><td>{v['mean_N']:+.4g}</td>"
        f"<td>{v['fraction']:.1%}</td></tr>"
        for k, v in d.phases.items()
    )
    structure = e(d.structure.description()) or "noise-like"
    caveats = "".join(f"<p><b>Caveat:</b> {e(c.text)}.</p>" for c in d.caveats)
    figures = "".join(f'<p><img src="{e(name)}" alt="{e(name)}"></p>' for name in images)
    return f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>gms-comp diagnosis</title>
<style>body{{font-family:sans-serif;max-width:1040px;margin:auto}}
table{{border-collapse:collapse}}td,th{{border:1px solid #aaa;padding:3px 8px}}</style>
</head><body>
<h1>Diagnosis: {e(d.effect)}</h1>
<ul>{sources}</ul>
<p>Gain {d.gain:.1%}: held-out force RMS {d.baseline_rms_N:.4g} N (baseline) to
{d.extended_rms_N:.4g} N (extended); noise {d.noise_rms_N:.3g} N.
Residual left by the extended model: {structure}.</p>
<h2>Effects kept (ranked)</h2>
<table><tr><th>#</th><th>effect</th><th>parameters</th><th>held-out RMS [N]</th></tr>
{rows or '<tr><td colspan="4">none</td></tr>'}</table>
{caveats}
<h2>Baseline residual by motion phase</h2>
<table><tr><th>phase</th><th>RMS [N]</th><th>mean [N]</th><th>samples</th></tr>{phases}</table>
<h2>Plots</h2>{figures}
</body></html>
"""
