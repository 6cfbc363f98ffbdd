"""Steady stripe/bristle model: rolling lines, Heathcote's limit, sliding force."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import integrate

from gms_comp.physics import ball_model as bm
from gms_comp.physics.config import BallConfig, ModelConfig, load_ball_config

# Heathcote's full-slip rolling line: the root of beta^3 - 3 beta + 1 = 0 in (0, 1).
HEATHCOTE_BETA = 2.0 * math.cos(4.0 * math.pi / 9.0)
NODES = 48


@pytest.fixture(scope="module")
def cfg() -> BallConfig:
    return load_ball_config()


@pytest.fixture(scope="module")
def model(cfg: BallConfig) -> bm.StripeModel:
    return bm.stripe_model(cfg, 50.0)


@pytest.fixture(scope="module")
def full_slip(model: bm.StripeModel) -> bm.StripeModel:
    # u_max -> 0: every bristle slips as soon as it enters.
    return dataclasses.replace(model, k_q_N_per_m3=1e40)


def test_heathcote_constant() -> None:
    beta = HEATHCOTE_BETA
    assert beta**3 - 3 * beta + 1 == pytest.approx(0.0, abs=1e-14)
    assert beta == pytest.approx(0.347296, abs=1e-6)


def test_table1_rolling_lines(cfg: BallConfig) -> None:
    result = bm.steady_state(cfg, 50.0)
    assert result.beta == pytest.approx(0.347, abs=0.005)
    # The seed: the minimum stays put for every lambda of the search (Fig. 5).
    assert all(abs(beta - 0.347) < 0.005 for beta in result.betas)
    assert result.lam == pytest.approx(cfg.bearing.ball_radius_m / result.contact.b_m)


@pytest.mark.parametrize("lam", [1e4, 1e6])
def test_full_slip_limit_is_heathcote(full_slip: bm.StripeModel, lam: float) -> None:
    assert bm.best_beta(full_slip, lam, NODES) == pytest.approx(HEATHCOTE_BETA, abs=1e-4)


def test_full_slip_force_is_traction_limit(full_slip: bm.StripeModel) -> None:
    # Every bristle carries C_v mu p(0, y): the ellipse integrates to C_v mu 4 Q / pi.
    force = bm.sliding_force_of(full_slip, 0.3, NODES)
    assert force == pytest.approx(1.2 * 0.001 * 50.0 * 4.0 / math.pi, rel=1e-9)


def test_sliding_force_matches_spec(cfg: BallConfig) -> None:
    assert bm.steady_state(cfg, 50.0).sliding_force_N == pytest.approx(0.069, abs=5e-4)
    assert bm.sliding_force_N(cfg) == pytest.approx(0.277, abs=2e-3)


def test_xi_vanishes_on_rolling_line(model: bm.StripeModel) -> None:
    beta = 0.35
    xi0 = bm.xi0_from_beta(beta, model.contact.b_m, model.ball_radius_m)
    xi = model.slip_ratio(np.array([beta * model.contact.b_m]), xi0)
    assert xi[0] == pytest.approx(0.0, abs=1e-18)


def test_b_minus_plus_bound_full_stick(model: bm.StripeModel) -> None:
    # Eq. (12): at b-/b+ the stick zone just reaches the trailing edge.
    beta = 0.35
    _, b_minus, b0, b_plus, b = model.area_bounds_m(beta)
    assert 0.0 < b_minus < b0 < b_plus < b
    xi0 = bm.xi0_from_beta(beta, model.contact.b_m, model.ball_radius_m)
    y = np.array([b_minus, b_plus])
    stick = model.stick_length_m(y, xi0)
    full = 2.0 * model.contact.half_length_m(y)
    np.testing.assert_allclose(stick, full, rtol=1e-9)
    np.testing.assert_allclose(
        model.slip_limit_m(y) / np.abs(model.slip_ratio(y, xi0)), full, rtol=1e-9
    )


def _bristle_traction(model: bm.StripeModel, x: float, y: float, xi0: float) -> float:
    """Eq. (1) for the steady field u = xi (x + a): stick k_q u, slip C_v f_max."""
    yy = np.array([y])
    u = model.slip_ratio(yy, xi0)[0] * (x + model.contact.half_length_m(yy)[0])
    limit = model.traction_limit_Pa(yy)[0]
    if abs(model.k_q_N_per_m3 * u) <= limit:
        return model.k_q_N_per_m3 * u
    return math.copysign(model.slip_exaggeration * limit, u)


@pytest.mark.parametrize("y_over_b", [0.05, 0.3, 0.345, 0.36, 0.7, 0.95])
def test_stripe_force_equals_pointwise_integral(model: bm.StripeModel, y_over_b: float) -> None:
    beta = 0.3474
    xi0 = bm.xi0_from_beta(beta, model.contact.b_m, model.ball_radius_m)
    y = y_over_b * model.contact.b_m
    half = float(model.contact.half_length_m(np.array([y]))[0])
    stick = float(model.stick_length_m(np.array([y]), xi0)[0])
    points = [-half + stick] if stick < 2 * half else None
    expected, _ = integrate.quad(
        lambda x: _bristle_traction(model, x, y, xi0), -half, half, points=points, epsabs=0
    )
    got = float(model.stripe_force_N_per_m(np.array([y]), xi0)[0])
    assert got == pytest.approx(expected, rel=1e-8)


def test_torque_quadrature_matches_adaptive(model: bm.StripeModel) -> None:
    beta, lam = 0.3, 5.0
    b = model.contact.b_m
    xi0 = bm.xi0_from_beta(beta, b, model.ball_radius_m)

    def integrand(y: float) -> float:
        yy = np.array([y])
        lever = math.sqrt((lam * b) ** 2 - y**2) - math.sqrt((lam * b) ** 2 - (beta * b) ** 2)
        return abs(float(model.stripe_force_N_per_m(yy, xi0)[0]) * lever)

    expected, _ = integrate.quad(
        integrand, 0.0, b, points=model.area_bounds_m(beta)[1:4], limit=200, epsabs=0
    )
    assert bm.friction_torque_Nm(model, beta, lam, NODES) == pytest.approx(2 * expected, rel=1e-7)


def test_mindlin_reading(cfg: BallConfig) -> None:
    physical = dataclasses.replace(cfg, model=ModelConfig(tangential_stiffness="mindlin"))
    result = bm.steady_state(physical, 50.0)
    # 1/G* = (2 - v1)/G1 + (2 - v2)/G2; k_q = 8 G* sqrt(ab) / (pi a b).
    g1, g2 = 210e9 / 2.6, 205e9 / 2.5
    g_star = 1.0 / (1.7 / g1 + 1.75 / g2)
    a, b = result.contact.a_m, result.contact.b_m
    assert result.k_q_N_per_m3 == pytest.approx(8 * g_star / (math.pi * math.sqrt(a * b)))
    assert result.beta == pytest.approx(0.347, abs=0.005)


def test_seed_reading_is_e_prime_per_mm(cfg: BallConfig) -> None:
    # E' = 224 555 N/mm^2 used as N/mm^3 = 2.24555e14 N/m^3.
    assert bm.steady_state(cfg, 50.0).k_q_N_per_m3 == pytest.approx(2.24555e14, rel=1e-5)
