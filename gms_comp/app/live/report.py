"""The commissioning report: one self-contained HTML page (plots embedded) and its JSON."""

from __future__ import annotations

import base64
import html
import io
import json
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from gms_comp import __version__
from gms_comp.app.live.commission import Commissioning
from gms_comp.atomic import write_text


def _png(fig: Any) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _plots(c: Commissioning, period_s: float) -> list[tuple[str, str]]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = []
    tr = c.recorded.trace
    fig, ax = plt.subplots(figsize=(7, 3.2))
    ax.plot(tr.position_m * 1e3, tr.force_N, lw=0.4)
    ax.set_xlabel("position [mm]")
    ax.set_ylabel("friction force [N]")
    ax.set_title("recorded: friction along the identification profile")
    out.append(("recording", _png(fig)))
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(7, 3.2))
    for v in c.verifications:
        t = np.arange(v.position_m.size) * period_s
        ax.plot(t, (v.target_m - v.position_m) * 1e6, lw=0.6, label=v.name)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("following error [um]")
    ax.set_title("reversal test: following error per feedforward")
    ax.legend(fontsize=8)
    out.append(("verification", _png(fig)))
    plt.close(fig)
    return out


def write_report(
    c: Commissioning, doc: dict[str, Any], folder: Path, period_s: float
) -> list[Path]:
    """``commission.json`` and ``commission.html`` in ``folder`` (created)."""
    folder.mkdir(parents=True, exist_ok=True)
    rows = "".join(
        f"<tr><td>{html.escape(name)}</td><td>{_um(v['peak_reversal_error_m'])}</td>"
        f"<td>{_um(v['rms_error_m'])}</td><td>{v['samples_missing']}</td></tr>"
        for name, v in doc["verification"].items()
    )
    diag = doc["diagnosis"]
    effects = ", ".join(e.get("effect", "?") for e in diag.get("effects", [])) or "none"
    images = "".join(
        f'<h2>{html.escape(title)}</h2><img alt="{html.escape(title)}" '
        f'src="data:image/png;base64,{data}">'
        for title, data in _plots(c, period_s)
    )
    page = f"""<!doctype html>
<html><head><meta charset="utf-8"><title>gms-comp commissioning</title>
<style>body{{font-family:sans-serif;max-width:60em;margin:2em auto}}
td,th{{padding:.2em .8em;text-align:right}}</style></head><body>
<h1>Commissioning</h1>
<p>gms-comp {__version__}, {datetime.now(UTC):%Y-%m-%d %H:%M UTC}; drive
{html.escape(json.dumps(doc["recording"]["drive"]))}; {doc["recording"]["samples"]} samples
recorded, {doc["recording"]["samples_missing"]} missing.</p>
<h2>Cause found</h2><p>{html.escape(str(diag["effect"]))}: {html.escape(effects)}</p>
<h2>Verification: the same reversal test per feedforward</h2>
<table><tr><th>feedforward</th><th>peak reversal error [um]</th><th>RMS error [um]</th>
<th>samples missing</th></tr>{rows}</table>
<p>Deployed: {html.escape(str(doc.get("deployed")))}, the table with the smallest peak
reversal error.</p>
{images}
</body></html>
"""
    return [
        write_text(folder / "commission.json", json.dumps(doc, indent=2) + "\n"),
        write_text(folder / "commission.html", page),
    ]


def _um(value: float | None) -> str:
    return "-" if value is None else f"{value * 1e6:.3f}"
