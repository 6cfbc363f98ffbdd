"""``simulate --via-can``: over a fault-free bus the closed loop equals the direct path.

The equivalent direct path (see the simulate command's docstring): no transport
delay of its own, the value held over the servo cycles of one CAN cycle, and
only the frame's quantization in between. The bounds are independent of the
code: the quantization step from the profile's definition (CiA 402: one per
mille of the rated current), and for the following error the peak response of
the cascade to a constant disturbance of half a step.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from firmware_bridge.link import CanFeedforwardLink
from firmware_bridge.settings import ProfileName, load_can_config
from gms_comp.app.cli import main
from gms_comp.config import default_config_path
from sim.link import DirectLink
from sim.scenarios import Scenario, load_scenario, run_strategies

SERVO_S = 2.5e-4


def _scenario() -> Scenario:
    s = load_scenario()
    short = dataclasses.replace(s.scenario, revolutions=0.3, dwell_s=0.05)
    return dataclasses.replace(s, scenario=short)


def _disturbance_error_bound_m(s: Scenario, current_A: float) -> float:
    """Peak position error of the cascade under a current disturbance, plus the encoder.

    A force step F is taken up by the velocity loop (crossover w_v, K_v = m w_v / k_f)
    within a velocity error of about F / (m w_v), which the position loop (w_p) turns
    into at most F / (m w_v w_p); a factor 2 covers the PI overshoot. Once the two
    runs differ at all, a reading may round to the other encoder step: one step,
    doubled for the same overshoot.
    """
    p, c = s.plant, s.controller
    force_N = current_A * p.force_constant_N_per_A
    wv, wp = (2 * math.pi * f for f in (c.velocity_bandwidth_Hz, c.position_bandwidth_Hz))
    return 2.0 * force_N / (p.moving_mass_kg * wv * wp) + 2.0 * p.encoder_resolution_m


@pytest.mark.parametrize(
    ("profile", "cycle_period_s"), [("cia402", 1e-3), ("cia402", 2 * SERVO_S), ("e2e", 1e-3)]
)
def test_via_can_equals_the_direct_path_within_quantization(
    profile: ProfileName, cycle_period_s: float
) -> None:
    s = _scenario()
    cfg = dataclasses.replace(load_can_config(), profile=profile, cycle_period_s=cycle_period_s)
    # cia402: one per mille of the rated current; e2e: the DBC's 0.1 mA.
    step_A = cfg.rated_current_A / 1000 if profile == "cia402" else 1e-4
    hold = round(cycle_period_s / SERVO_S)
    with CanFeedforwardLink(cfg, servo_period_s=SERVO_S) as can_link:
        over_can = run_strategies(s, ["gms"], link=lambda _d: can_link)["gms"]
        assert can_link.report()["bus_load"] < 0.7
    direct = run_strategies(s, ["gms"], link=lambda _d: DirectLink(0, hold))["gms"]
    ff_can, ff_direct = over_can.feedforward_A, direct.feedforward_A
    assert np.max(np.abs(ff_direct)) > 50 * step_A  # the feedforward spans many steps
    assert np.max(np.abs(ff_direct)) < cfg.max_current_A  # no saturation by the bus
    assert np.max(np.abs(ff_can - ff_direct)) <= 0.5 * step_A + 1e-12
    bound_m = _disturbance_error_bound_m(s, 0.5 * step_A)
    assert np.max(np.abs(over_can.error_m - direct.error_m)) <= bound_m
    assert bound_m < np.max(np.abs(direct.error_m))  # the bound is below the signal


def test_simulate_via_can_from_the_cli(tmp_path: Path) -> None:
    config = tmp_path / "short.toml"
    config.write_text(
        default_config_path().read_text() + "[scenario]\nrevolutions = 0.3\ndwell_s = 0.05\n"
    )
    out = tmp_path / "scores.json"
    assert main(["simulate", str(config), "--via-can", "-o", str(out)]) == 0
    report = json.loads(out.read_text())
    assert report["scenario"]["via_can"] is True
    peaks = {k: v["peak_reversal_error_m"] for k, v in report["strategies"].items()}
    assert peaks["gms"] < peaks["none"]
