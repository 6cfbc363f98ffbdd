"""Plots of a diagnosis: residual against time, position, velocity, and by phase."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from .run import Diagnosis


def write_report(diagnosis: Diagnosis, folder: str | Path) -> list[Path]:
    """Write the report's PNG files into ``folder``; return their paths."""
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    s = diagnosis.series
    base = s["force_N"] - s["baseline_N"]
    ext = s["force_N"] - s["extended_N"]
    paths = []
    fig, axes = plt.subplots(3, 1, figsize=(10, 9))
    for ax, key, unit in zip(
        axes, ("time_s", "position_m", "velocity_m_s"), ("s", "m", "m/s"), strict=True
    ):
        ax.plot(s[key], base, ",", label="baseline residual")
        ax.plot(s[key], ext, ",", label="extended residual")
        ax.set_xlabel(f"{key} [{unit}]")
        ax.set_ylabel("residual [N]")
    axes[0].legend(markerscale=20)
    axes[0].set_title(f"effect: {diagnosis.effect}, gain {diagnosis.gain:.1%}")
    fig.tight_layout()
    paths.append(out / "residual.png")
    fig.savefig(paths[-1], dpi=100)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(10, 4))
    names = list(diagnosis.phases)
    ax.barh(names, [diagnosis.phases[n]["rms_N"] for n in names])
    ax.set_xlabel("baseline residual RMS [N]")
    fig.tight_layout()
    paths.append(out / "phases.png")
    fig.savefig(paths[-1], dpi=100)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(10, 4))
    ax.plot(s["time_s"], s["force_N"], lw=0.5, label="measured")
    ax.plot(s["time_s"], s["baseline_N"], lw=0.5, label="baseline")
    ax.plot(s["time_s"], s["extended_N"], lw=0.5, label="extended")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("force [N]")
    ax.legend()
    fig.tight_layout()
    paths.append(out / "force.png")
    fig.savefig(paths[-1], dpi=100)
    plt.close(fig)
    return paths
