"""The streaming friction observer: scaling, limits, fallback and guarded adaptation."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gms_comp.gms import GmsParams, GmsStream
from gms_comp.runtime.observer import CompensatorConfig, FrictionObserver
from gms_comp.tables.table import Extension, Fidelity, GmsTable

SERVO_S = 2.5e-4
KF = 50.0


def _table(params: GmsParams) -> GmsTable:
    """A bare table around ``params``."""
    return GmsTable(params, source_config="test", source_sha256="", fidelity=Fidelity(0.0, 0.0))


@dataclass
class Scripted:
    """A force model that returns a prescribed sequence."""

    forces: list[float]

    def reset(self) -> None:
        self._i = 0

    def step(self, position_m: float, velocity_m_s: float) -> float:
        self._i += 1
        return self.forces[self._i - 1]


def _single_element(limit_N: float = 10.0) -> GmsParams:
    return GmsParams(np.array([1e6]), np.array([limit_N]))


def test_current_is_level_times_force_over_force_constant() -> None:
    obs = FrictionObserver(_table(_single_element(10.0)), KF, SERVO_S, level=2.0)
    out = [obs.step(x, 1e-3) for x in np.linspace(0.0, 1e-4, 20)]
    # Sliding: 10 N per element, level 2, 50 N/A -> 0.4 A.
    assert out[-1] == pytest.approx(2.0 * 10.0 / KF)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-1e4, 1e4), min_size=2, max_size=60))
def test_output_respects_saturation_and_rate_limit(forces: list[float]) -> None:
    cfg = CompensatorConfig(current_limit_A=1.5, rate_limit_A_per_s=400.0)
    obs = FrictionObserver(Scripted(forces), KF, SERVO_S, config=cfg)
    previous = 0.0
    for _ in forces:
        now = obs.step(0.0, 0.0)
        assert abs(now) <= cfg.current_limit_A + 1e-12
        assert abs(now - previous) <= cfg.rate_limit_A_per_s * SERVO_S + 1e-12
        previous = now


def test_disable_ramps_to_zero_and_enable_is_bumpless() -> None:
    cfg = CompensatorConfig(rate_limit_A_per_s=400.0)  # 0.1 A per cycle
    obs = FrictionObserver(Scripted([25.0] * 40), KF, SERVO_S, config=cfg)
    for _ in range(10):
        obs.step(0.0, 0.0)
    assert obs.output_A == pytest.approx(0.5)
    obs.disable()
    ramp = [obs.step(0.0, 0.0) for _ in range(10)]
    assert ramp[:5] == pytest.approx([0.4, 0.3, 0.2, 0.1, 0.0])
    assert ramp[-1] == 0.0
    obs.enable()
    back = [obs.step(0.0, 0.0) for _ in range(10)]
    assert back[-1] == pytest.approx(0.5)


def test_non_finite_model_force_falls_back_to_no_feedforward() -> None:
    obs = FrictionObserver(Scripted([10.0, 10.0, math.nan, 10.0]), KF, SERVO_S)
    outputs = [obs.step(0.0, 0.0) for _ in range(4)]
    assert not obs.enabled
    assert all(math.isfinite(o) for o in outputs)
    assert abs(outputs[-1]) < abs(outputs[1])


def _adapt(obs: FrictionObserver, true_level: float, cycles: int, speed: float) -> None:
    """Slide at ``speed``; the drive's current carries ``true_level`` times the model."""
    for k in range(cycles):
        obs.step(k * speed * SERVO_S, speed)
        drive_current = true_level * obs.model_force_N / KF
        obs.adapt(drive_current, 0.0, speed)


def test_adaptation_converges_to_the_true_level() -> None:
    cfg = CompensatorConfig(adaptation_rate_per_s=20.0)
    obs = FrictionObserver(GmsStream(_single_element()), KF, SERVO_S, level=1.0, config=cfg)
    _adapt(obs, true_level=1.3, cycles=8000, speed=0.01)  # 2 s, 40 time constants
    assert obs.level == pytest.approx(1.3, rel=1e-3)


def test_adaptation_is_bounded_and_ignores_outliers_and_standstill() -> None:
    cfg = CompensatorConfig(adaptation_rate_per_s=20.0, adaptation_level_bounds=(0.9, 1.1))
    obs = FrictionObserver(GmsStream(_single_element()), KF, SERVO_S, level=1.0, config=cfg)
    _adapt(obs, true_level=1.3, cycles=8000, speed=0.01)
    assert obs.level == pytest.approx(1.1)  # clamped at the upper bound
    obs.reset()
    _adapt(obs, true_level=5.0, cycles=2000, speed=0.01)  # implausible: ignored
    assert obs.level == 1.0
    _adapt(obs, true_level=1.05, cycles=2000, speed=1e-4)  # below the minimum speed
    assert obs.level == 1.0


def test_adaptation_bounds_must_bracket_one() -> None:
    from gms_comp.config import parse_section
    from gms_comp.errors import ConfigError

    doc = {"compensator": {"adaptation_level_bounds": [1.2, 2.0]}}
    with pytest.raises(ConfigError, match=r"compensator\.adaptation_level_bounds"):
        parse_section(doc, "c.toml", "compensator", CompensatorConfig)


def test_physical_extensions_apply_and_measurement_ones_do_not() -> None:
    table = dataclasses.replace(
        _table(_single_element(10.0)),
        extensions=(
            Extension("viscous", {"c_Ns_per_m": 100.0}),
            Extension("inertia", {"mass_kg": 1000.0}),  # the measurement's, not friction
        ),
    )
    obs = FrictionObserver(table, KF, SERVO_S)
    speed = 0.01
    out = [obs.step(k * speed * SERVO_S, speed) for k in range(40)]
    # Sliding: 10 N of elements + 100 Ns/m * 0.01 m/s of viscous = 11 N -> 0.22 A.
    assert out[-1] == pytest.approx(11.0 / KF)


def _dwell_difference(context: dict[str, float] | None) -> float:
    """Largest extra force of a dwell_time extension over its GMS along slide - hold - slide.

    The hold (0.5 s) dithers by +-0.2 um at 500 Hz (0.6 mm/s peak): never below the
    runtime's default standstill speed (0.1 mm/s), but within the 1 um rest band the
    table's context says the fit used."""
    from gms_comp.runtime.observer import ExtendedGms

    gms = _single_element(10.0)
    table = dataclasses.replace(
        _table(gms),
        extensions=(Extension("dwell_time", {"gamma": 0.5, "tau_s": 0.1, "reach": 0.5}),),
        extension_context=context,
    )
    model, plain = ExtendedGms(table, SERVO_S), GmsStream(gms)
    model.reset()
    plain.reset()
    worst, x, k = 0.0, 0.0, 0
    w = 2 * math.pi * 500.0
    for phase, steps in (("slide", 200), ("hold", 2000), ("slide", 200)):
        for _ in range(steps):
            k += 1
            if phase == "slide":
                x, v = x + 1e-2 * SERVO_S, 1e-2
                x0, t0 = x, k * SERVO_S
            else:
                t = k * SERVO_S - t0
                x, v = x0 + 0.2e-6 * math.sin(w * t), 0.2e-6 * w * math.cos(w * t)
            worst = max(worst, abs(model.step(x, v) - plain.step(x, v)))
    return worst


def test_extensions_see_the_path_as_the_table_context_says() -> None:
    """A diagnosed table carries how its fit saw rest; the observer must see it alike."""
    fitted = {"standstill_speed_m_s": 1e-4, "reversal_deadband_m": 0.0, "rest_band_m": 1e-6}
    assert _dwell_difference(fitted) > 0.5  # a dwell of 0.5 s: limits 1.9 x 10 N
    assert _dwell_difference(None) == pytest.approx(0.0, abs=1e-9)  # the default: no rest
