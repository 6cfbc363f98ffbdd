"""A mangled clock never changes the named effect silently (issue 74), through the CLI.

``gms-comp demo-trace`` writes a trace with a known effect; its clock is then mangled as
loggers do (time in ms, a change of rate, a gap, jitter) with tests/tracefiles.py, and
``gms-comp diagnose`` must name the same effect, or refuse in one line and name the same
effect on the piece it is pointed at, and say in its JSON and summary how the clock was
read. One diagnosis is 5-10 s: these are few, and marked slow.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from tracefiles import csv_text, jittered, rate_change, with_gap

from gms_comp.app.cli import main

pytestmark = pytest.mark.slow
HIDDEN, SEED = "viscous", 1


@pytest.fixture(scope="module")
def demo(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    """The demo trace and its diagnosis as recorded."""
    folder = tmp_path_factory.mktemp("clock")
    path = folder / "demo.csv"
    assert main(["demo-trace", str(path), "--effect", HIDDEN, "--seed", str(SEED)]) == 0
    return path, _diagnosed(path)


def _diagnosed(path: Path, *extra: str) -> dict[str, Any]:
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["diagnose", str(path), "--json", *extra]) == 0
    doc: dict[str, Any] = json.loads(out.getvalue())
    return doc


def _columns(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t, x, f = np.loadtxt(path, delimiter=",", skiprows=1).T
    return t, x, f


def _write(path: Path, t: np.ndarray, x: np.ndarray, f: np.ndarray, time: str = "time_s") -> Path:
    path.write_bytes(csv_text({time: t, "position_m": x, "force_N": f}))
    return path


def test_the_recorded_trace_names_its_effect(demo: tuple[Path, dict[str, Any]]) -> None:
    _, doc = demo
    assert doc["effect"] == HIDDEN
    assert "resampled_from_Hz" not in doc["input"] and "note" not in doc["input"]


def test_ms_stamps_are_refused_and_with_their_map_give_the_same_result(
    demo: tuple[Path, dict[str, Any]], capsys: pytest.CaptureFixture[str]
) -> None:
    path, doc = demo
    t, x, f = _columns(path)
    ms = _write(path.with_name("ms.csv"), t * 1e3, x, f, time="t[ms]")
    capsys.readouterr()
    assert main(["diagnose", str(ms), "--map", "time_s=t[ms]"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "looks like ms (--map time_s=(t[ms])*0.001)" in err
    again = _diagnosed(ms, "--map", "time_s=t[ms]*0.001")
    assert again["effect"] == doc["effect"]
    for name, value in doc["parameters"].items():
        assert again["parameters"][name] == pytest.approx(value, rel=1e-6)


def test_a_change_of_rate_is_resampled_said_and_names_the_same_effect(
    demo: tuple[Path, dict[str, Any]],
) -> None:
    path, doc = demo
    t, x, f = _columns(path)
    kept = rate_change(t.size, t.size // 2, 2)  # the first half logged at 500 Hz
    mixed = _diagnosed(_write(path.with_name("rate.csv"), t[kept], x[kept], f[kept]))
    assert mixed["input"]["resampled_from_Hz"] == [pytest.approx(500.0), pytest.approx(1000.0)]
    assert mixed["input"]["sample_rate_Hz"] == pytest.approx(500.0)
    assert "resampled onto a uniform 500 Hz clock" in mixed["input"]["note"]
    assert mixed["effect"] == doc["effect"]


def test_a_gap_is_refused_and_its_longest_segment_names_the_same_effect(
    demo: tuple[Path, dict[str, Any]], capsys: pytest.CaptureFixture[str]
) -> None:
    path, doc = demo
    t, x, f = _columns(path)
    at = int(0.85 * t.size)
    gap = _write(path.with_name("gap.csv"), with_gap(t, at, 1000.0), x, f)
    capsys.readouterr()
    assert main(["diagnose", str(gap)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"row {at + 2}, column time_s: a gap of 1000 s" in err
    piece = _diagnosed(gap, "--segment", "longest")
    assert piece["input"]["segment"] == {"index": 1, "of": 2, "samples": [0, at - 1]}
    assert piece["effect"] == doc["effect"]


def test_jitter_is_read_as_recorded_and_names_the_same_effect(
    demo: tuple[Path, dict[str, Any]],
) -> None:
    path, doc = demo
    t, x, f = _columns(path)
    shaken = _diagnosed(_write(path.with_name("jitter.csv"), jittered(t, 0.06, 3), x, f))
    assert "note" not in shaken["input"]
    assert shaken["effect"] == doc["effect"]
