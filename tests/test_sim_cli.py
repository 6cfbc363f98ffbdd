"""``gms-comp simulate`` end to end: the JSON it writes and the configs it refuses."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gms_comp.app.cli import main
from gms_comp.config import default_config_path

SHORT = """
[scenario]
revolutions = 0.3
dwell_s = 0.05
"""


def _config(tmp_path: Path, extra: str) -> Path:
    path = tmp_path / "scenario.toml"
    path.write_text(default_config_path().read_text() + extra)
    return path


def test_simulate_writes_scores_for_every_strategy(tmp_path: Path) -> None:
    out = tmp_path / "scores.json"
    plot = tmp_path / "reversal.png"
    code = main(
        ["simulate", str(_config(tmp_path, SHORT)), "--output", str(out), "--plot", str(plot)]
    )
    assert code == 0
    report = json.loads(out.read_text())
    strategies = report["strategies"]
    assert set(strategies) == {"none", "coulomb_viscous", "lugre", "gms"}
    for scores in strategies.values():
        assert set(scores) == {"peak_reversal_error_m", "rms_error_m", "peak_stop_error_m"}
        assert all(v > 0 for v in scores.values())
    # The truth is the ball model; the table only approximates it, yet it must help.
    assert strategies["gms"]["peak_reversal_error_m"] < strategies["none"]["peak_reversal_error_m"]
    assert plot.stat().st_size > 0


def test_two_axis_circle_scores_the_contour(tmp_path: Path) -> None:
    out = tmp_path / "scores.json"
    plot = tmp_path / "reversal.png"
    config = _config(tmp_path, SHORT + 'circle_axis = "xy"\n')
    assert main(["simulate", str(config), "-o", str(out), "--plot", str(plot)]) == 0
    report = json.loads(out.read_text())
    assert report["scenario"]["axes"] == 2
    for scores in report["strategies"].values():
        circ = scores["circularity"]
        assert set(circ) == {"peak_quadrant_error_m", "rms_radial_error_m"}
        assert all(v > 0 for v in circ.values())
    assert (tmp_path / "reversal_circularity.png").stat().st_size > 0


def test_drive_command_loop_runs_the_same_scenario(tmp_path: Path) -> None:
    # [controller] structure = "position_velocity": the replay's loop (sim.position_loop)
    # on the same truth and strategies. Without velocity feedforward its following error is
    # the loop's lag (tens of um), so the feedforward trims the reversal peak, no more.
    out = tmp_path / "scores.json"
    config = _config(tmp_path, SHORT + '[controller]\nstructure = "position_velocity"\n')
    assert main(["simulate", str(config), "-o", str(out)]) == 0
    peaks = {
        k: v["peak_reversal_error_m"] for k, v in json.loads(out.read_text())["strategies"].items()
    }
    assert peaks["gms"] < 0.9 * peaks["none"]


def test_json_flag_prints_only_json_and_says_what_was_simulated(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = _config(tmp_path, SHORT)
    assert main(["simulate", str(config), "--json"]) == 0
    captured = capsys.readouterr()
    report = json.loads(captured.out)  # stdout is the JSON and nothing else
    assert "simulating gms" in captured.err  # progress on stderr
    assert main(["simulate", str(config)]) == 0
    summary = capsys.readouterr().out
    duration = report["scenario"]["duration_s"]
    assert f"4 strategies x {duration:.3g} s = {4 * duration:.3g} s of axis time" in summary
    factor = summary.split("(")[-1].split("x real time")[0]
    assert float(factor) > 0  # never "0x"


def test_output_paths_are_checked_before_running(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    missing = tmp_path / "no-such-folder" / "scores.json"
    assert main(["simulate", "-o", str(missing)]) == 2
    assert "does not exist" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("extra", "names"),
    [
        ('[scenario]\ntrajectory = "square"\n', "scenario.trajectory"),
        ('[scenario]\ncircle_axis = "xyz"\n', "scenario.circle_axis"),
        ("[scenario]\ncircle_axis = 2\n", "scenario.circle_axis"),
        ("[scenario]\nrevolutions = 1e3\n", "lasts"),
        (
            '[scenario]\ntrajectory = "step_stop"\ndwell_s = 60\n'
            "[controller]\nservo_rate_Hz = 1e5\n",
            "servo cycles",
        ),
        ("[scenario]\nfeed_m_s = 2.0\nradius_m = 0.001\n", "plant.current_limit_A"),
        ("[controller]\nservo_rate_Hz = -4000\n", "controller.servo_rate_Hz"),
        ("[controller]\nvelocity_bandwidth_Hz = 3000.0\n", "controller.velocity_bandwidth_Hz"),
        ("[plant]\nmass_kg = 30\n", "plant.mass_kg"),
        ("[compensator]\nfeed = 'future'\n", "compensator.feed"),
        ("[controller]\nvelocity_fir = [0.7, 0.7]\n", "controller.velocity_fir"),
    ],
)
def test_bad_scenarios_are_refused_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: str, names: str
) -> None:
    code = main(["simulate", str(_config(tmp_path, extra))])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("gms-comp simulate: error:")
    assert err.count("\n") == 1
    assert names in err
