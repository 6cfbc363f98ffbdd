"""`gms-comp model`: the JSON keys the issue names, in SI units, and the text summary."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from gms_comp.cli import main
from gms_comp.config import default_config_path


def _json(capsys: pytest.CaptureFixture[str], argv: list[str]) -> dict[str, Any]:
    assert main(argv) == 0
    data: dict[str, Any] = json.loads(capsys.readouterr().out)
    return data


def test_json_keys_and_values(capsys: pytest.CaptureFixture[str]) -> None:
    data = _json(capsys, ["model", "--json"])
    assert data["contact"]["a_m"] == pytest.approx(65.157e-6, rel=1e-3)
    assert data["contact"]["b_m"] == pytest.approx(307.177e-6, rel=1e-3)
    assert data["contact"]["p0_Pa"] == pytest.approx(1192.8e6, rel=1e-3)
    assert data["contact"]["approach_m"] == pytest.approx(2.0484e-6, rel=1e-3)
    assert data["rolling_lines"]["beta"] == pytest.approx(0.347, abs=0.005)
    assert data["rolling_lines"]["lambda"] >= 1.0
    beta, b, r = data["rolling_lines"]["beta"], data["contact"]["b_m"], 3.175e-3
    assert data["rolling_lines"]["xi0"] == pytest.approx(
        -((beta * b) ** 2) / (2 * r**2 - (beta * b) ** 2)
    )
    assert data["friction"]["sliding_force_N"] == pytest.approx(0.277, abs=2e-3)


def test_explicit_config_equals_default(capsys: pytest.CaptureFixture[str]) -> None:
    implicit = _json(capsys, ["model", "--json"])
    explicit = _json(capsys, ["model", str(default_config_path()), "--json"])
    assert implicit == explicit


def test_ball_set_sums_its_balls(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = (
        default_config_path()
        .read_text()
        .replace("ball_loads_N = [50.0, 50.0, 50.0, 50.0]", "ball_loads_N = [50.0, 100.0]")
    )
    path = tmp_path / "two.toml"
    path.write_text(text)
    data = _json(capsys, ["model", str(path), "--json"])
    per_ball = data["friction"]["sliding_force_per_ball_N"]
    assert len(per_ball) == 2
    assert math.isclose(sum(per_ball), data["friction"]["sliding_force_N"])
    # Friction grows with load (the traction limit integrates to C_v mu 4 Q / pi).
    assert per_ball[0] == pytest.approx(0.069, abs=5e-4)
    assert per_ball[0] < per_ball[1] < 1.2e-3 * 4 * 100 / math.pi


def test_text_summary(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["model"]) == 0
    out = capsys.readouterr().out
    assert "beta = 0.347" in out and "a = 65.157 um" in out


def test_console_entry_point() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "gms_comp", "model", "--json"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert "sliding_force_N" in json.loads(result.stdout)["friction"]


def test_plot_writes_four_pngs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["model", "--json", "--plot", str(tmp_path / "figs")]) == 0
    json.loads(capsys.readouterr().out)  # stdout stays one JSON object
    names = sorted(p.name for p in (tmp_path / "figs").iterdir())
    assert names == [
        "fig3_stick_slip.png",
        "fig4_fields.png",
        "fig5_torque_map.png",
        "fig8_hysteresis.png",
    ]
    for name in names:
        assert (tmp_path / "figs" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
