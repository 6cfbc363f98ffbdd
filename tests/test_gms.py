"""Properties of the GMS model against analytic expectations (Al-Bender et al. 2005)."""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from indepfriction import play_operator, velocity_level

from gms_comp.gms import GmsParams, GmsStream, simulate, simulate_elements
from sim.kernels import truth_force, truth_pack

SPEED_m_s = 1e-2  # far above the level transition speed: the level is slip_level
STEP_m = 2e-8


def elements(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return 10 ** rng.uniform(5, 7, n), rng.uniform(0.01, 0.1, n)


def path(extrema: list[float], step_m: float = STEP_m) -> tuple[np.ndarray, np.ndarray]:
    """Straight segments between extrema at constant speed; each extremum is sampled."""
    xs = [np.array([extrema[0]])]
    vs = [np.array([0.0])]
    for a, b in itertools.pairwise(extrema):
        n = max(1, math.ceil(abs(b - a) / step_m))
        xs.append(np.linspace(a, b, n + 1)[1:])
        vs.append(np.full(n, math.copysign(SPEED_m_s, b - a)))
    return np.concatenate(xs), np.concatenate(vs)


def virgin(k: np.ndarray, w: np.ndarray, x: float, level: float = 1.0) -> float:
    """sign(x) sum_i (k_i |x| while stuck, else level W_i): the seed's bristle law.

    At level 1 this is sum_i min(k_i x, W_i), Al-Bender's virgin curve.
    """
    stuck = k * abs(x) <= w
    return math.copysign(float(np.sum(np.where(stuck, k * abs(x), level * w))), x)


element_sets = st.builds(elements, st.integers(1, 12), st.integers(0, 10_000))


@settings(max_examples=40, deadline=None)
@given(element_sets, st.floats(1e-8, 2e-6), st.floats(0.5, 2.0))
def test_virgin_curve_is_sum_of_clipped_elements(
    kw: tuple[np.ndarray, np.ndarray], end_m: float, slip_level: float
) -> None:
    k, w = kw
    p = GmsParams(k, w, slip_level=slip_level)
    x, v = path([0.0, end_m])
    force, _ = simulate(p, x, v)
    expected = [virgin(k, w, xi, slip_level) for xi in x[1:]]
    np.testing.assert_allclose(force[1:], expected, rtol=1e-9, atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(element_sets, st.floats(1e-8, 3e-6), st.floats(0.1, 2.0))
def test_masing_reversal_curve_is_virgin_curve_scaled_by_two(
    kw: tuple[np.ndarray, np.ndarray], turn_m: float, back_fraction: float
) -> None:
    k, w = kw
    x, v = path([0.0, turn_m, turn_m * (1 - back_fraction)])
    force, _ = simulate(GmsParams(k, w), x, v)
    after = x <= x[np.argmax(x)]
    after[: np.argmax(x)] = False
    f_turn = virgin(k, w, turn_m)
    expected = [f_turn - 2 * virgin(k, w, (turn_m - xi) / 2) for xi in x[after]]
    np.testing.assert_allclose(force[after], expected, rtol=1e-9, atol=1e-12)


def test_non_local_memory_force_depends_on_past_extremum() -> None:
    k, w = elements(8, 1)
    end_m = 0.2e-6
    forces = []
    for turn_m in (0.6e-6, 1.5e-6):
        x, v = path([0.0, turn_m, end_m])
        f, _ = simulate(GmsParams(k, w), x, v)
        expected = virgin(k, w, turn_m) - 2 * virgin(k, w, (turn_m - end_m) / 2)
        assert f[-1] == pytest.approx(expected, rel=1e-9)
        forces.append(f[-1])
    assert abs(forces[0] - forces[1]) > 1e-3 * max(abs(f) for f in forces)


@settings(max_examples=40, deadline=None)
@given(
    element_sets,
    st.floats(-1.0, 1.0),
    st.floats(0.05, 0.95),
    st.floats(0.05, 0.95),
    st.floats(1.0, 2.0),
)
def test_inner_loop_is_wiped_out_and_closes_at_its_return_point(
    kw: tuple[np.ndarray, np.ndarray], b: float, p_frac: float, q_frac: float, c_over: float
) -> None:
    """Path b -> p -> q -> p -> c (inner loop p, q inside [b, c]) ends like b -> c."""
    k, w = kw
    scale = 2e-6
    start, b_m = -3 * scale, b * scale  # start saturated: a well defined state
    c_m = b_m + c_over * scale
    p_m = b_m + p_frac * (c_m - b_m)
    q_m = b_m + q_frac * (p_m - b_m)
    x_loop, v_loop = path([start, b_m, p_m, q_m, c_m])
    x_direct, v_direct = path([start, b_m, c_m])
    f_loop, s_loop = simulate(GmsParams(k, w), x_loop, v_loop)
    f_direct, s_direct = simulate(GmsParams(k, w), x_direct, v_direct)
    np.testing.assert_allclose(s_loop.element_force_N, s_direct.element_force_N, atol=1e-12)
    assert f_loop[-1] == pytest.approx(f_direct[-1], abs=1e-12)
    # Return-point memory: back at p the force equals the force first reached there.
    at_p = np.flatnonzero(np.isclose(x_loop, p_m, rtol=0, atol=1e-15))
    assert f_loop[at_p[-1]] == pytest.approx(f_loop[at_p[0]], abs=1e-9)


@settings(max_examples=30, deadline=None)
@given(
    element_sets,
    st.lists(st.floats(-3e-6, 3e-6), min_size=2, max_size=6),
    st.floats(1.0, 2.0),
    st.floats(0.0, 5.0),
)
def test_closed_loops_dissipate(
    kw: tuple[np.ndarray, np.ndarray], extrema: list[float], slip_level: float, viscous: float
) -> None:
    k, w = kw
    p = GmsParams(k, w, slip_level=slip_level, viscous_Ns_per_m=viscous)
    cycle = [0.0, *extrema, 0.0]
    x, v = path(cycle + cycle[1:], step_m=1e-9)
    force, _ = simulate(p, x, v)
    second = slice(len(x) // 2, None)  # after one cycle the state is periodic
    xs, fs = x[second], force[second]
    work_J = float(np.sum(0.5 * (fs[1:] + fs[:-1]) * np.diff(xs)))
    scale_J = float(np.sum(w)) * slip_level * 1e-9  # trapezoid error at the kinks
    assert work_J >= -scale_J * len(extrema)


def test_level_drops_at_a_stop_and_returns_on_restart() -> None:
    """The seed's peaks: a fully slipping contact loses the factor C_v at rest."""
    k, w = elements(6, 2)
    c_v = 1.2
    p = GmsParams(k, w, slip_level=c_v)
    x = np.array([0.0, 1e-5, 1e-5, 1.01e-5])
    v = np.array([0.0, SPEED_m_s, 0.0, SPEED_m_s])
    force, _ = simulate(p, x, v)
    assert force[1] == pytest.approx(c_v * w.sum())
    assert force[2] == pytest.approx(w.sum())
    assert force[3] == pytest.approx(c_v * w.sum())


@pytest.mark.parametrize("exponent", [1.0, 2.0])
def test_a_rational_tail_is_the_lorentzian_in_the_kernel_too(exponent: float) -> None:
    """Tail 1: the level is 1 + (C_v - 1) q / (1 + q), q = (|v| / v_t)^delta (at delta 2
    the independent generator's law, tests/indepfriction.py), in ``level`` and in the
    kernel (a slipping contact carries level W at each speed); a tail of 1e6 is the
    exponential within 1e-5."""
    k, w = elements(4, 3)
    c_v, v_t = 1.25, 2e-4
    p = GmsParams(k, w, slip_level=c_v, transition_velocity_m_s=v_t,
                  transition_exponent=exponent, transition_tail=1.0)  # fmt: skip
    speeds = np.geomspace(v_t / 30, 300 * v_t, 40)
    q = (speeds / v_t) ** exponent
    law = 1.0 + (c_v - 1.0) * q / (1.0 + q)
    np.testing.assert_allclose(p.level(speeds), law, rtol=1e-12)
    if exponent == 2.0:
        np.testing.assert_allclose(p.level(speeds), velocity_level(speeds, c_v, v_t), rtol=1e-12)
    # far into slip at each speed: 1 mm in 1 um steps, then the force is level W
    for speed, expected in zip(speeds[::8], law[::8], strict=True):
        x = np.linspace(0.0, 1e-3, 1001)
        force, _ = simulate(p, x, np.full(x.size, speed))
        assert force[-1] == pytest.approx(expected * w.sum(), rel=1e-12)
    near = dataclasses.replace(p, transition_tail=1e6)
    far = dataclasses.replace(p, transition_tail=math.inf)
    np.testing.assert_allclose(near.level(speeds), far.level(speeds), rtol=1e-5)


@pytest.mark.parametrize("tail", [1.0, 1e12])
def test_every_compiled_path_sees_the_tail(tail: float) -> None:
    """The batch kernel, the stream and the simulated axis's truth step give the level of
    ``level()`` in slip at each speed, for a rational tail and for one so large that
    (1 + q / p)^-p must come out as exp(-q) (a naive power loses it at 1e12)."""
    k, w = elements(3, 4)
    p = GmsParams(k, w, slip_level=1.3, transition_velocity_m_s=1e-4, transition_tail=tail)
    if tail > 1e6:
        exponential = dataclasses.replace(p, transition_tail=math.inf)
        np.testing.assert_allclose(p.level([1e-4, 2e-4]), exponential.level([1e-4, 2e-4]),
                                   rtol=1e-9)  # fmt: skip
    for speed in (3e-5, 1e-4, 4e-4):
        x = np.linspace(0.0, 1e-3, 501)
        expected = float(p.level(speed)[()]) * w.sum()
        assert simulate(p, x, np.full(x.size, speed))[0][-1] == pytest.approx(expected, rel=1e-12)
        stream, truth = GmsStream(p), GmsStream(p)
        pack = truth_pack(truth)
        assert pack is not None
        for xi in x:
            last = stream.step(float(xi), speed)
            on_axis = truth_force(pack, float(xi), speed)
        assert last == pytest.approx(expected, rel=1e-12)
        assert on_axis == pytest.approx(expected, rel=1e-12)


def _wandering_path() -> tuple[np.ndarray, np.ndarray]:
    """Strokes of 5-200 um at 0.02-5 mm/s either way with rests, at 2 kHz: the speed
    crosses v_t in both directions many times, slipping elements speed up and slow down."""
    rng = np.random.default_rng(11)
    pieces, x0 = [], 0.0
    for _ in range(30):
        n = int(rng.integers(50, 600))
        s = np.linspace(0.0, 1.0, n)
        stroke = rng.choice([-1.0, 1.0]) * rng.uniform(5e-6, 2e-4)
        pieces += [
            x0 + stroke * (3 * s**2 - 2 * s**3),
            np.full(int(rng.integers(0, 80)), x0 + stroke),
        ]
        x0 += stroke
    x = np.concatenate(pieces)
    return x, np.gradient(x, 5e-4)


@pytest.mark.parametrize("c_v", [1.3, 1.0, 0.8])
def test_a_limit_that_follows_the_level_is_the_independent_play_operator(c_v: float) -> None:
    """``limit_follows_level``: every element is a spring clipped at s(v) W_i, the
    independent generator's law (tests/indepfriction.play_operator), in the batch kernel,
    the element columns, the stream and the simulated axis's truth step. With C_v = 1 it
    is the seed's law; with C_v 1.3 the seed's law is another model (its slipping elements
    jump to C_v W_i)."""
    x, v = _wandering_path()
    k, w = elements(5, 8)
    p = GmsParams(k, w, slip_level=c_v, transition_velocity_m_s=3e-4, transition_tail=1.0,
                  limit_follows_level=True)  # fmt: skip
    level = velocity_level(np.abs(v), c_v, 3e-4)
    expected = play_operator(np.diff(x, prepend=x[0]), k, w / k, level)
    force = simulate(p, x, v)[0]
    np.testing.assert_allclose(force, expected, rtol=1e-9, atol=1e-12 * w.sum())
    np.testing.assert_allclose(simulate_elements(p, x, v).sum(axis=1), force, rtol=1e-12)
    stream, truth = GmsStream(p), GmsStream(p)
    pack = truth_pack(truth)
    assert pack is not None
    streamed = [stream.step(float(xi), float(vi)) for xi, vi in zip(x, v, strict=True)]
    on_axis = [truth_force(pack, float(xi), float(vi)) for xi, vi in zip(x, v, strict=True)]
    np.testing.assert_array_equal(streamed, force)
    np.testing.assert_array_equal(on_axis, force)
    # the virgin curve at a fixed level: each element clipped at level W_i
    ramp = np.linspace(0.0, 60e-6, 301)
    step, held = np.diff(ramp, prepend=0.0), np.full(ramp.size, c_v)
    np.testing.assert_allclose(p.virgin_curve(ramp, c_v), play_operator(step, k, w / k, held),
                               rtol=1e-12, atol=1e-15)  # fmt: skip
    seed_law = simulate(dataclasses.replace(p, limit_follows_level=False), x, v)[0]
    gap = float(np.max(np.abs(seed_law - force)))
    assert gap < 1e-9 * w.sum() if c_v == 1.0 else gap > 0.05 * w.sum()


@pytest.mark.parametrize("attraction_per_s", [30.0, 300.0, 3000.0])
def test_finite_attraction_relaxes_exponentially_in_time(attraction_per_s: float) -> None:
    """After a stop the slipping element is drawn back to C_v W at rate C / C_v."""
    c_v, w, speed = 1.5, 0.1, 1e-3
    p = GmsParams(
        np.array([1e9]), np.array([w]), slip_level=c_v, attraction_rate_per_s=attraction_per_s
    )
    step = 1e-7
    x_go = np.arange(1, 2001) * step
    x = np.concatenate([[0.0, 1e-5, 1e-5], 1e-5 + x_go])
    v = np.concatenate([[0.0, speed, 0.0], np.full(x_go.size, speed)])
    force, _ = simulate(p, x, v)
    expected = c_v * w - (c_v - 1) * w * np.exp(-attraction_per_s * x_go / (c_v * speed))
    np.testing.assert_allclose(force[3:], expected, rtol=1e-9)


def test_rate_independence_as_attraction_grows() -> None:
    """The same path at two speeds: the force difference vanishes as C -> infinity."""
    k, w = elements(8, 3)
    x, _ = path([0.0, 2e-6, 2e-6, 3e-6, 1e-6, 1e-6, 4e-6])
    direction = np.sign(np.diff(x, prepend=x[0]))
    gaps = []
    for rate in (1e5, 1e6, 1e7, 1e8, math.inf):
        p = GmsParams(k, w, slip_level=1.3, attraction_rate_per_s=rate)
        f_slow, _ = simulate(p, x, direction * 1e-2)
        f_fast, _ = simulate(p, x, direction * 1e-1)
        gaps.append(float(np.max(np.abs(f_slow - f_fast))))
    assert gaps == sorted(gaps, reverse=True)
    assert gaps[0] > 1e-3 * w.sum()
    assert gaps[-1] == 0.0


def test_viscous_term_adds_sigma2_v() -> None:
    k, w = elements(4, 4)
    x, v = path([0.0, 1e-5])
    plain, _ = simulate(GmsParams(k, w), x, v)
    damped, _ = simulate(GmsParams(k, w, viscous_Ns_per_m=7.0), x, v)
    np.testing.assert_allclose(damped - plain, 7.0 * v, atol=1e-12)


def test_stream_equals_batch_and_batch_continues_from_state() -> None:
    k, w = elements(16, 5)
    p = GmsParams(
        k,
        w,
        slip_level=1.2,
        transition_velocity_m_s=1e-3,
        attraction_rate_per_s=500.0,
        viscous_Ns_per_m=0.3,
    )
    t = np.linspace(0, 1, 3001)
    x = 2e-6 * np.sin(2 * np.pi * 3 * t) * np.exp(-t)
    v = np.gradient(x, t)
    whole, _ = simulate(p, x, v)
    first, state = simulate(p, x[:1000], v[:1000])
    rest, _ = simulate(p, x[1000:], v[1000:], state)
    stream = GmsStream(p)
    stepped = [stream.step(float(a), float(b)) for a, b in zip(x, v, strict=True)]
    np.testing.assert_array_equal(np.concatenate([first, rest]), whole)
    np.testing.assert_allclose(stepped, whole, rtol=0, atol=1e-15)
    stream.reset()
    assert stream.step(float(x[5]), 0.0) == 0.0


def test_element_forces_are_each_element_alone_and_sum_to_the_force() -> None:
    """One pass for all elements gives, column by column, each element simulated alone
    (a GMS's elements do not interact), and the row sums plus sigma2 v are the force."""
    k, w = elements(7, 6)
    p = GmsParams(
        k, w, slip_level=1.3, transition_velocity_m_s=2e-4, transition_exponent=1.4,
        attraction_rate_per_s=800.0, viscous_Ns_per_m=0.5,
    )  # fmt: skip
    t = np.linspace(0, 1, 4001)
    x = 3e-6 * np.sin(2 * np.pi * 2 * t) + 1e-6 * np.sin(2 * np.pi * 11 * t)
    v = np.gradient(x, t)
    columns = simulate_elements(p, x, v)
    for i in range(k.size):
        alone = GmsParams(
            k[i : i + 1], w[i : i + 1], slip_level=1.3, transition_velocity_m_s=2e-4,
            transition_exponent=1.4, attraction_rate_per_s=800.0,
        )  # fmt: skip
        np.testing.assert_array_equal(columns[:, i], simulate(alone, x, v)[0])
    np.testing.assert_allclose(columns.sum(axis=1) + 0.5 * v, simulate(p, x, v)[0], atol=1e-12)
    assert simulate_elements(p, x[:0], v[:0]).shape == (0, 7)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"stiffness_N_per_m": [-1.0]}, "stiffness_N_per_m"),
        ({"limit_N": [-0.1]}, "limit_N"),
        ({"slip_level": 0.0}, "slip_level"),
        ({"attraction_rate_per_s": math.nan}, "attraction_rate_per_s"),
        ({"viscous_Ns_per_m": -1.0}, "viscous_Ns_per_m"),
        ({"transition_tail": 0.0}, "transition_tail"),
        ({"transition_tail": math.nan}, "transition_tail"),
        ({"limit_follows_level": 1}, "limit_follows_level"),
        ({"limit_follows_level": True, "attraction_rate_per_s": 100.0}, "limit_follows_level"),
    ],
)
def test_bad_parameters_are_refused(kwargs: dict[str, object], field: str) -> None:
    args: dict[str, object] = {"stiffness_N_per_m": [1e6], "limit_N": [0.1], **kwargs}
    with pytest.raises(ValueError, match=field):
        GmsParams(**args)  # type: ignore[arg-type]


def test_reversal_restarts_from_the_stick_limit() -> None:
    """Seed Eq. 1: a slipping bristle carries C_v W; reversed, it sticks again from W."""
    k, w, c_v = 1e6, 0.1, 1.2
    p = GmsParams(np.array([k]), np.array([w]), slip_level=c_v)
    x = np.array([0.0, 1e-6, 1e-6 - 5e-8])
    force, _ = simulate(p, x, np.array([0.0, SPEED_m_s, -SPEED_m_s]))
    assert force[1] == pytest.approx(c_v * w)
    assert force[2] == pytest.approx(w - k * 5e-8)
