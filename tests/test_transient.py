"""Transient bristle-field model of the ball set against independent expectations."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import integrate

from gms_comp.physics import ball_model as bm
from gms_comp.physics.config import BallConfig, load_ball_config
from gms_comp.physics.profiles import seed_fig7_profile
from gms_comp.physics.transient import BallSetFriction


def _with_grid(cfg: BallConfig, stripes: int, bristles: int) -> BallConfig:
    model = dataclasses.replace(cfg.model, stripes_per_area=stripes, bristles_per_stripe=bristles)
    return dataclasses.replace(cfg, model=model)


@pytest.fixture(scope="module")
def cfg() -> BallConfig:
    return load_ball_config()


@pytest.fixture(scope="module")
def friction(cfg: BallConfig) -> BallSetFriction:
    return BallSetFriction(cfg)


@pytest.fixture(scope="module")
def fig7(friction: BallSetFriction) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    t, x, v = seed_fig7_profile(sample_rate_Hz=10_000.0)
    return t, x, v, friction.force(x, v)


def _run_in_m(cfg: BallConfig) -> float:
    """Carriage travel that replaces every bristle of the widest contact."""
    a = max(bm.stripe_model(cfg, q).contact.a_m for q in cfg.stand.ball_loads_N)
    return 2.0 * a / cfg.stand.rolling_distance_per_travel


def test_steady_sliding_reaches_steady_model(cfg: BallConfig, friction: BallSetFriction) -> None:
    x = np.linspace(0.0, 3 * _run_in_m(cfg), 3000)
    force = friction.force(x, np.full_like(x, 0.01))
    tail = force[x > 1.05 * _run_in_m(cfg)]
    np.testing.assert_allclose(tail, bm.sliding_force_N(cfg), rtol=4e-3)


def test_reversing_direction_flips_force(friction: BallSetFriction) -> None:
    _, x, v = seed_fig7_profile(sample_rate_Hz=5_000.0)
    np.testing.assert_allclose(friction.force(-x, -v), -friction.force(x, v), atol=1e-15)


def test_fig8_rectangular_hysteresis(cfg: BallConfig, fig7: tuple[np.ndarray, ...]) -> None:
    _, x, v, force = fig7
    steady = bm.sliding_force_N(cfg)
    # Once a whole contact width has rolled since the reversal, the force is the
    # steady sliding force of the direction of motion: the flat sides of Fig. 8.
    reversal = int(np.argmax(x))
    away_out = (v > 0) & (x > _run_in_m(cfg))
    away_back = (v < 0) & (x < x[reversal] - _run_in_m(cfg))
    np.testing.assert_allclose(force[away_out], steady, rtol=5e-3)
    np.testing.assert_allclose(force[away_back], -steady, rtol=5e-3)


def _stop_level_ratio(cfg: BallConfig) -> float:
    """Moving over resting steady force from the steady model: C_v on slip only."""
    ratios = []
    for load in cfg.stand.ball_loads_N:
        model = bm.stripe_model(cfg, load)
        beta = bm.steady_state(cfg, load).beta
        resting = dataclasses.replace(model, slip_exaggeration=1.0)
        ratios.append(bm.sliding_force_of(model, beta, 48) / bm.sliding_force_of(resting, beta, 48))
    return float(np.mean(ratios))


def test_stops_drop_by_slip_exaggeration(cfg: BallConfig, fig7: tuple[np.ndarray, ...]) -> None:
    _, x, v, force = fig7
    # Stops of the way back, after the field has become steady (not the first two).
    starts = np.flatnonzero((v[1:] == 0) & (v[:-1] < 0)) + 1
    late = starts[x[starts] < x.max() - _run_in_m(cfg)]
    assert len(late) >= 6
    ratios = force[late - 1] / force[late]
    np.testing.assert_allclose(ratios, _stop_level_ratio(cfg), rtol=3e-3)
    # The force stays put while the carriage rests (rate-independent model).
    for k in late:
        assert force[k + 10] == force[k]


def test_full_slip_limit(cfg: BallConfig) -> None:
    # u_max -> 0 (tiny mu): bristles slip at once; the set carries C_v mu 4 Q / pi per
    # ball while moving and exactly 1/C_v of it at a stop.
    mu = 1e-9
    slippery = dataclasses.replace(
        cfg, bearing=dataclasses.replace(cfg.bearing, friction_coefficient=mu)
    )
    friction = BallSetFriction(slippery)
    x = np.array([0.0, 1e-6, 2e-6, 2e-6])
    v = np.array([0.0, 0.01, 0.01, 0.0])
    force = friction.force(x, v)
    expected = 1.2 * mu * 4 * sum(slippery.stand.ball_loads_N) / math.pi
    assert force[2] == pytest.approx(expected, rel=2e-3)
    assert force[3] == pytest.approx(expected / 1.2, rel=2e-3)


def _stick_stiffness_N_per_m(model: bm.StripeModel, xi0: float) -> float:
    """k_q int int |xi| dA over the whole ellipse: dF/ds when every bristle sticks."""

    def stripe(y: float) -> float:
        xi = float(model.slip_ratio(np.array([y]), xi0)[0])
        return 2.0 * float(model.contact.half_length_m(y)) * abs(xi)

    b0 = math.sqrt(-xi0 * 2 * model.ball_radius_m**2 / (1 - xi0))
    inner, _ = integrate.quad(stripe, 0.0, model.contact.b_m, points=[b0])
    return 2.0 * inner * model.k_q_N_per_m3


def test_presliding_slope_after_reversal(cfg: BallConfig, friction: BallSetFriction) -> None:
    # Right after a reversal every bristle sticks: dF/dx = r k_q int int |xi| dA per ball.
    slope = sum(
        _stick_stiffness_N_per_m(bm.stripe_model(cfg, q), bm.steady_state(cfg, q).xi0)
        * cfg.stand.rolling_distance_per_travel
        for q in cfg.stand.ball_loads_N
    )
    d = np.array([0.0, 1e-10, 2e-10, 3e-10])
    force = friction.reversal_curve(d)
    np.testing.assert_allclose(np.diff(force) / 1e-10, slope, rtol=1e-2)
    # The branch unwinds from -F_s/ratio to +F_s within one contact width.
    far = friction.reversal_curve(np.array([1.05 * _run_in_m(cfg)]))
    assert far[0] == pytest.approx(bm.sliding_force_N(cfg), rel=5e-3)


def test_virgin_curve_is_monotone_and_saturates(cfg: BallConfig, friction: BallSetFriction) -> None:
    x = np.linspace(0.0, 1.2 * _run_in_m(cfg), 400)
    curve = friction.virgin_curve(x)
    assert curve[0] == 0.0
    rising = x < 2e-6  # well inside the presliding regime
    assert np.all(np.diff(curve[rising]) > 0.0)
    assert curve[-1] == pytest.approx(bm.sliding_force_N(cfg), rel=5e-3)


def test_streaming_matches_batch(friction: BallSetFriction) -> None:
    _, x, v = seed_fig7_profile(sample_rate_Hz=2_000.0)
    friction.reset()
    streamed = np.array([friction.step(float(p), float(s)) for p, s in zip(x, v, strict=True)])
    np.testing.assert_allclose(streamed, friction.force(x, v), rtol=0, atol=1e-15)
    friction.reset()
    assert friction.step(0.5, 0.0) == 0.0


def test_grid_refinement_converges(cfg: BallConfig) -> None:
    steady = bm.sliding_force_N(cfg)
    x = np.linspace(0.0, 1.5 * _run_in_m(cfg), 300)
    reference = BallSetFriction(_with_grid(cfg, 32, 128)).virgin_curve(x)
    mean_errors, end_errors = [], []
    for stripes, bristles in [(4, 16), (8, 32), (16, 64)]:
        curve = BallSetFriction(_with_grid(cfg, stripes, bristles)).virgin_curve(x)
        mean_errors.append(float(np.mean(np.abs(curve - reference))) / steady)
        end_errors.append(abs(curve[-1] / steady - 1.0))
    # The whole virgin curve converges (first order in the grid spacing) ...
    assert mean_errors[0] > mean_errors[1] > mean_errors[2]
    assert mean_errors[1] < 5e-3
    # ... and its end onto the steady model's sliding force.
    assert max(end_errors) < 1e-2
    assert abs(reference[-1] / steady - 1.0) < 5e-4


def test_result_independent_of_sampling(friction: BallSetFriction) -> None:
    # The conveyance is exact for any monotone step: one step equals many.
    x_fine = np.linspace(0.0, 4e-4, 2000)
    fine = friction.force(x_fine, np.full_like(x_fine, 0.01))[-1]
    coarse = friction.force(np.array([0.0, 4e-4]), np.array([0.01, 0.01]))[-1]
    assert coarse == pytest.approx(fine, rel=1e-9)


def test_mindlin_reading_has_shorter_presliding(cfg: BallConfig) -> None:
    # k_q(mindlin) > k_q(seed) here, so the field saturates over a shorter travel.
    physical = dataclasses.replace(
        cfg, model=dataclasses.replace(cfg.model, tangential_stiffness="mindlin")
    )
    x = np.linspace(0.0, 5e-6, 50)
    seed, mindlin = BallSetFriction(cfg).virgin_curve(x), BallSetFriction(physical).virgin_curve(x)
    assert np.all(mindlin[1:] > seed[1:])


def test_unequal_loads_sum(cfg: BallConfig) -> None:
    two = dataclasses.replace(cfg, stand=dataclasses.replace(cfg.stand, ball_loads_N=(30.0, 80.0)))
    single = [
        BallSetFriction(
            dataclasses.replace(cfg, stand=dataclasses.replace(cfg.stand, ball_loads_N=(q,)))
        )
        for q in (30.0, 80.0)
    ]
    _, x, v = seed_fig7_profile(sample_rate_Hz=2_000.0)
    np.testing.assert_allclose(
        BallSetFriction(two).force(x, v), single[0].force(x, v) + single[1].force(x, v), rtol=1e-12
    )


def test_rejects_mismatched_arrays(friction: BallSetFriction) -> None:
    with pytest.raises(ValueError):
        friction.force(np.zeros(3), np.zeros(4))
