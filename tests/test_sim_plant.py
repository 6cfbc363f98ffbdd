"""The simulated axis and its controller against python-control and first principles."""

from __future__ import annotations

import math
from typing import Any

import control
import numpy as np
import pytest

from gms_comp.config import parse_section
from gms_comp.errors import ConfigError
from sim.controller import CascadeController, ControllerConfig, design
from sim.plant import LinearMotorAxis, PlantConfig, ZeroFriction, dynamics, plant_params

SERVO_S = 2.5e-4


def _exact(**changes: Any) -> PlantConfig:
    """The default plant with an ideal encoder (no quantization, no noise)."""
    return PlantConfig(**{"encoder_resolution_m": 0.0, "position_noise_m": 0.0, **changes})


def _run_axis(cfg: PlantConfig, levels: np.ndarray) -> np.ndarray:
    axis = LinearMotorAxis(cfg, ZeroFriction(), SERVO_S)
    out = []
    for level in levels:
        axis.step(float(level))
        out.append(axis.position_m)
    return np.array(out)


@pytest.mark.parametrize("order", [1, 2])
def test_linear_axis_matches_python_control(order: int) -> None:
    cfg = _exact(current_loop_order=order)
    levels = np.random.default_rng(order).uniform(-3.0, 3.0, 80)
    # Independent model: current loop times a double integrator, from first principles,
    # under the drive's zero-order hold.
    wc = 2 * math.pi * cfg.current_loop_bandwidth_Hz
    if order == 1:
        loop = control.tf([wc], [1, wc])
    else:
        loop = control.tf([wc**2], [1, 2 * cfg.current_loop_damping * wc, wc**2])
    mech = control.tf([cfg.force_constant_N_per_A / cfg.moving_mass_kg], [1, 0, 0])
    held = control.c2d(loop * mech, SERVO_S, "zoh")
    expected = control.forced_response(held, U=levels).outputs[1:]
    got = _run_axis(cfg, levels)[:-1]
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-6 * np.max(np.abs(expected)))


def test_dynamics_matches_nonlinear_solver_with_saturation() -> None:
    cfg = _exact(current_limit_A=1.0)
    levels = np.random.default_rng(7).uniform(-3.0, 3.0, 40)
    # A staircase for the ODE solver: each step switches within 1 ns of the cycle edge.
    edges = np.arange(len(levels)) * SERVO_S
    t = np.sort(np.concatenate([edges, edges[1:] - 1e-9, [len(levels) * SERVO_S]]))
    u = levels[np.minimum((t / SERVO_S + 1e-6).astype(int), len(levels) - 1)]
    sys = control.nlsys(dynamics, None, inputs=2, states=3, outputs=3, dt=0)
    resp = control.input_output_response(
        sys,
        t,
        np.vstack([u, np.zeros_like(u)]),
        params=plant_params(cfg),
        solve_ivp_kwargs={"rtol": 1e-10, "atol": 1e-16, "max_step": SERVO_S / 4},
    )
    at_edges = np.isin(t, edges[1:]) | (t == t[-1])
    expected = resp.states[0][at_edges]
    got = _run_axis(cfg, levels)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-5 * np.max(np.abs(expected)))


def test_current_never_exceeds_limit() -> None:
    cfg = _exact(current_limit_A=2.0)
    axis = LinearMotorAxis(cfg, ZeroFriction(), SERVO_S)
    for command in [50.0] * 20 + [-50.0] * 40:
        axis.step(command)
        assert abs(axis.current_A) <= cfg.current_limit_A + 1e-12


def test_sign_positive_current_accelerates_forward() -> None:
    axis = LinearMotorAxis(_exact(), ZeroFriction(), SERVO_S)
    for _ in range(10):
        axis.step(1.0)
    assert axis.velocity_m_s > 0 and axis.position_m > 0


def test_energy_is_conserved_without_friction_or_current() -> None:
    cfg = _exact()
    axis = LinearMotorAxis(cfg, ZeroFriction(), SERVO_S)
    axis.state[:] = [0.0, 0.05, 0.0, 0.0]
    for _ in range(100):
        axis.step(0.0)
    assert axis.velocity_m_s == pytest.approx(0.05, rel=1e-12)
    assert axis.position_m == pytest.approx(0.05 * 100 * SERVO_S, rel=1e-9)


def test_encoder_quantizes_to_its_resolution() -> None:
    cfg = PlantConfig(encoder_resolution_m=1e-6, position_noise_m=0.0)
    axis = LinearMotorAxis(cfg, ZeroFriction(), SERVO_S)
    axis.state[:] = [3.4e-6, 0.0, 0.0, 0.0]
    assert axis.measure() == pytest.approx(3e-6)


def test_closed_loop_is_stable_and_tracks_a_step() -> None:
    plant = _exact()
    ctl_cfg = ControllerConfig()
    ctl = CascadeController(design(plant, ctl_cfg), plant.current_limit_A)
    axis = LinearMotorAxis(plant, ZeroFriction(), ctl_cfg.servo_period_s)
    measured = 0.0
    for _ in range(2000):  # 0.5 s: many position-loop time constants
        measured = axis.step(ctl.step(measured, 1e-6, 0.0, 0.0))
    assert axis.position_m == pytest.approx(1e-6, rel=1e-3)


def test_discrete_pi_has_the_designed_gain_and_integrator() -> None:
    plant = PlantConfig()
    cfg = ControllerConfig(discretization="tustin")
    pi = design(plant, cfg).velocity_pi
    kv = plant.moving_mass_kg * 2 * math.pi * cfg.velocity_bandwidth_Hz
    kv /= plant.force_constant_N_per_A
    assert pi.a == pytest.approx(1.0)  # an integrator stays an integrator
    # Tustin PI: direct gain Kv (1 + wi Ts / 2).
    wi_ts = 2 * math.pi * cfg.integral_corner_Hz * cfg.servo_period_s
    assert pi.d == pytest.approx(kv * (1 + wi_ts / 2))


@pytest.mark.parametrize(
    ("section", "text", "key"),
    [
        ("controller", "velocity_bandwidth_Hz = 3000.0", "controller.velocity_bandwidth_Hz"),
        ("controller", "position_bandwidth_Hz = 500.0", "controller.position_bandwidth_Hz"),
        ("plant", "moving_mass_kg = -1.0", "plant.moving_mass_kg"),
        ("plant", "current_loop_order = 3", "plant.current_loop_order"),
    ],
)
def test_bad_sections_are_refused_naming_the_key(section: str, text: str, key: str) -> None:
    import tomllib

    doc = {section: tomllib.loads(text)}
    cls = {"controller": ControllerConfig, "plant": PlantConfig}[section]
    with pytest.raises(ConfigError, match=key):
        parse_section(doc, "x.toml", section, cls)


def test_energy_balance_with_the_ball_model_truth() -> None:
    from gms_comp.physics.config import load_ball_config
    from gms_comp.physics.transient import BallSetFriction
    from sim.plant import ScaledFriction

    cfg = _exact()
    truth = ScaledFriction(BallSetFriction(load_ball_config()), cfg.ball_set_count)
    axis = LinearMotorAxis(cfg, truth, SERVO_S)
    motor_J = friction_J = 0.0
    for k in range(1600):  # 0.4 s of a 5 Hz current: reversals and sliding
        x, v, i = axis.position_m, axis.velocity_m_s, axis.current_A
        axis.step(0.6 * math.sin(2 * math.pi * 5.0 * k * SERVO_S))
        # The friction force is held over the cycle: its work is exact.
        friction_J += axis.friction_force_N * (axis.position_m - x)
        mean_power_W = 0.5 * (i * v + axis.current_A * axis.velocity_m_s)
        motor_J += cfg.force_constant_N_per_A * mean_power_W * SERVO_S
    kinetic_J = 0.5 * cfg.moving_mass_kg * axis.velocity_m_s**2
    assert friction_J > 0  # friction only ever takes energy out
    assert motor_J - friction_J == pytest.approx(kinetic_J, abs=0.01 * motor_J)
