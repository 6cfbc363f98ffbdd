"""The effects catalogue: forms from the spec, path quantities, batch == streaming."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal

from gms_comp.gms import GmsParams, simulate
from gms_comp.runtime import effects as fx
from gms_comp.runtime.effects import dwell_time


def _ctx(
    t: np.ndarray, x: np.ndarray, f: np.ndarray | None = None, still: float = 1e-4
) -> fx.Context:
    v = np.gradient(x, t)
    a = np.gradient(v, t)
    return fx.Context.along(t, x, v, a, np.ones_like(t) if f is None else f, still)


def _triangle(n: int = 2000, amp: float = 1e-3, dt: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(n) * dt
    x = amp * (2 / np.pi) * np.arcsin(np.sin(2 * np.pi * t / (n * dt / 2)))
    return t, x


def test_path_distance_since_reversal_and_direction() -> None:
    # +1 mm in 1000 samples, then back: reversal at the peak
    t = np.arange(2001) * 1e-3
    x = np.concatenate([np.linspace(0, 1e-3, 1001), np.linspace(1e-3, 0, 1001)[1:]])
    v = np.where(np.arange(2001) <= 1000, 1.0, -1.0) * 1e-3
    ctx = fx.Context.along(t, x, v, 0 * t, 0 * t)
    assert ctx.direction[500] == 1 and ctx.direction[1500] == -1
    # no reversal before the turning point: the last one is unknown, any transient gone
    assert np.isinf(ctx.distance_since_reversal_m[1000])
    # counted from the turning point at 1 mm
    assert ctx.distance_since_reversal_m[1500] == pytest.approx(0.5e-3, rel=1e-6)


@pytest.mark.parametrize("residue", [-1e-71, 1e-71, 0.0])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_the_first_stroke_after_a_rest_is_no_reversal(residue: float, sign: float) -> None:
    # at rest for 0.3 s, then 1 mm either way: a smoothed speed's rounding residue at the
    # first sample (of either sign) must not set a direction the first stroke then reverses
    n_rest, n_move = 300, 1000
    t = np.arange(n_rest + n_move) * 1e-3
    x = sign * np.concatenate([np.zeros(n_rest), np.linspace(0, 1e-3, n_move + 1)[1:]])
    v = np.gradient(x, t)
    v[0] = residue
    ctx = fx.Context.along(t, x, v, 0 * t, 0 * t, reversal_deadband_m=1e-9)
    assert np.all(np.isinf(ctx.distance_since_reversal_m))
    assert np.all(ctx.direction[:n_rest] == 0.0)
    assert np.all(ctx.direction[n_rest:] == sign)
    # hence no reversal transient anywhere on it
    assert not np.any(fx.ReversalTransient(3.0, 5e-5).apply(ctx, np.zeros(t.size)))


def test_steps_and_ringing_within_the_deadband_are_no_reversal() -> None:
    # a slow ramp read through a 0.1 um encoder, with ringing of a fifth of a step
    t = np.arange(4000) * 1e-3
    x = np.round(1e-6 * t / 1e-7) * 1e-7 + 2e-8 * np.sin(2 * np.pi * 40 * t)
    v = np.gradient(x, t)
    ctx = fx.Context.along(t, x, v, 0 * t, 0 * t, 0.0, reversal_deadband_m=6e-8)
    first = int(np.argmax(np.abs(x - x[0]) > 6e-8))  # the first step sets the direction
    assert 0 < first < 200
    assert np.all(ctx.direction[:first] == 0.0) and np.all(ctx.direction[first:] == 1.0)
    assert ctx.distance_since_reversal_m[-1] > 3.9e-6


@pytest.mark.parametrize("step", [4.2e-8, 1e-9])
def test_hindsight_dates_a_reversal_at_its_turning_point(step: float) -> None:
    # a 1 mm sine read through an encoder, turning every 0.5 s, its vertices 0.4 of a
    # count off the counts (at 42 nm the position stays on one count for 5 samples
    # there); a causal reversal is known once the retreat exceeds the deadband (7
    # steps: 3.5 ms at 42 nm), in hindsight it dates from the last sample at the vertex
    t = np.arange(4000) * 5e-4
    x = np.round((1e-3 * np.sin(2 * np.pi * t)) / step + 0.4) * step
    v = 2e-3 * np.pi * np.cos(2 * np.pi * t)
    band, still = 7 * step, 1e-7  # a standstill at most at a vertex's own sample
    causal = fx.Context.along(t, x, v, 0 * t, 0 * t, still, reversal_deadband_m=band)
    seen = fx.Context.along(
        t, x, v, 0 * t, 0 * t, still, reversal_deadband_m=band, hindsight=True
    )  # fmt: skip
    vertices = np.array([500, 1500, 2500, 3500])  # t = 0.25 s + k 0.5 s
    flips = np.flatnonzero(np.diff(seen.direction[1:]) != 0) + 2
    late = np.flatnonzero(np.diff(causal.direction[1:]) != 0) + 2
    # the last of the samples the quantised vertex stays on (x[k] == x[vertex])
    last = [k - 50 + np.flatnonzero(x[k - 50 : k + 50] == x[k])[-1] for k in vertices]
    if step > 1e-8:
        assert min(np.count_nonzero(x[k - 50 : k + 50] == x[k]) for k in vertices) >= 3
    np.testing.assert_array_equal(flips, np.array(last) + 1)
    assert np.all(late > flips)
    # the distance since the reversal runs on from the vertex, and is the causal one after
    s = seen.distance_since_reversal_m
    for f, g in zip(flips, late, strict=True):
        assert s[f] == pytest.approx(abs(x[f] - x[f - 1]), abs=1e-18)  # one move on
        assert np.all(np.diff(s[f : g + 5]) >= 0.0)
        assert np.all(seen.direction[f:g] == causal.direction[g])
    # elsewhere the two agree
    off = np.ones(t.size, bool)
    for f, g in zip(flips, late, strict=True):
        off[f:g] = False
    np.testing.assert_array_equal(seen.direction[off], causal.direction[off])
    np.testing.assert_array_equal(
        seen.distance_since_reversal_m[off], causal.distance_since_reversal_m[off]
    )


def test_hindsight_dates_a_reversal_after_a_rest_where_the_rest_ends() -> None:
    # 0.2 mm forward, a 1 s rest that dithers by a count and settles a count back, then
    # back: the motion turns where the rest ends, not at its last count at the extreme
    step, n = 1e-8, 1000
    t = np.arange(3 * n) * 1e-3
    x = np.concatenate([np.linspace(0.0, 2e-4, n), np.full(n, 2e-4), np.linspace(2e-4, 0.0, n)])
    x[n + 50 : n + 100 : 2] -= step
    x[n + 100 : 2 * n] -= step
    x[2 * n :] = np.linspace(2e-4 - 2 * step, 0.0, n)
    x = np.round(x / step) * step
    v = np.gradient(x, t)
    v[n : 2 * n] = 0.0
    ctx = fx.Context.along(
        t, x, v, 0 * t, 0 * t, 1e-5, reversal_deadband_m=2.5 * step, rest_band_m=1.5 * step,
        hindsight=True,
    )  # fmt: skip
    assert np.all(ctx.resting[n + 20 : 2 * n - 1] > 0)
    flip = int(np.flatnonzero(np.diff(ctx.direction[1:]) != 0)[-1]) + 2
    assert 2 * n - 1 <= flip <= 2 * n + 1
    assert np.all(ctx.direction[n + 1 : flip] == 1.0)
    # so a reversal transient starts with the return stroke, not within the rest
    transient = fx.ReversalTransient(1.0, 1e-5).apply(ctx, np.zeros(t.size))
    assert np.all(np.abs(transient[n + 1 : 2 * n - 1]) < 1e-6)


def test_path_dwell_is_length_of_last_standstill() -> None:
    dt = 1e-3
    v = np.concatenate([np.full(100, 1e-3), np.zeros(300), np.full(100, 1e-3)])
    x = np.cumsum(v) * dt
    t = np.arange(v.size) * dt
    ctx = fx.Context.along(t, x, v, 0 * t, 0 * t)
    assert ctx.dwell_s[50] == 0.0  # no standstill yet
    assert ctx.dwell_s[450] == pytest.approx(0.3, abs=1e-9)
    # a record that begins at rest: how long it stood before is unknown, so no dwell
    late = fx.Context.along(t[100:] - t[100], x[100:], v[100:], 0 * t[100:], 0 * t[100:])
    assert late.moving[350] == 1.0 and late.dwell_s[350] == 0.0
    # ... but the motion resumed from a rest: a start, and a break-away after it
    np.testing.assert_array_equal(late.starts(), [300])
    assert late.resting[0] == 1.0 and late.after_rest()[350]
    np.testing.assert_array_equal(ctx.starts(), [400])
    assert not ctx.after_rest()[50] and ctx.after_rest()[450]
    assert late.starts(hold_s=0.31).size == 0  # its rest was 0.3 s as seen
    assert ctx.moving[200] == 0.0 and ctx.moving[450] == 1.0
    # counted from the rest position: samples 400-450 each moved 1 um
    assert ctx.distance_since_start_m[450] == pytest.approx(51 * 1e-6, rel=1e-6)


def test_slow_break_away_is_dated_by_the_rest_band_not_the_speed() -> None:
    # 0.1 s at 1 mm/s, 0.3 s at rest, read through a 5 nm encoder, then a start whose
    # speed rises by 1 mm/s per second: it stays below a 0.5 mm/s standstill speed for
    # 0.5 s and 125 um
    dt, step = 1e-3, 5e-9
    t = np.arange(1000) * dt
    moving = np.clip(t - 0.4, 0.0, None)
    x_true = 1e-3 * np.minimum(t, 0.1) + 1e-3 * 0.5 * moving**2
    x = np.round(x_true / step) * step
    v = np.where(t < 0.1, 1e-3, 1e-3 * moving)
    by_speed = fx.Context.along(t, x, v, 0 * t, 1.0 + 0 * t, 5e-4)
    by_band = fx.Context.along(t, x, v, 0 * t, 1.0 + 0 * t, 5e-4, rest_band_m=1.5 * step)
    rest = 200
    first_step = rest + int(np.argmax(np.abs(x[rest:] - x[rest]) > 1.5 * step))
    late = 500
    # by speed: the axis counts as resting until 0.9 s, 125 um after it left
    assert by_speed.resting[late] == 1.0
    # by the band: resting ends on the first steps beyond it, the dwell is the whole stop
    # and the distance counts from where it stood
    assert by_band.resting[first_step - 1] == 1.0 and by_band.resting[first_step] == 0.0
    assert by_band.dwell_s[late] == pytest.approx(0.3 + (first_step - 400) * dt, abs=1.5 * dt)
    assert by_band.distance_since_start_m[late] == pytest.approx(x[late] - x[rest], abs=step)
    # the break-away window of a dwell gain follows the band's start: an element of 2 um
    # raised by 1 + 0.3 ln(1 + 0.3 / 0.05) = 1.58 stretches on from 2 to 3.2 um
    effect = fx.DwellTime(0.3, 0.05, 0.3)
    element = GmsParams(np.array([1.0 / 2e-6]), np.array([1.0]))
    speed_ctx = dataclasses.replace(by_speed, gms=element)
    band_ctx = dataclasses.replace(by_band, gms=element)
    assert np.all(effect.basis(speed_ctx, effect.shape())[first_step:late] == 0.0)
    assert np.count_nonzero(effect.basis(band_ctx, effect.shape())[first_step:late]) > 10


def test_a_slow_turnaround_is_not_a_rest_but_a_stop_there_is() -> None:
    # 1 um reversals at 1 Hz through a 5 nm encoder: at each turnaround the position
    # stays within the 7.5 nm band for 2 sqrt(2 x 7.5 nm / (A w^2)) = 39 ms (> 20 ms),
    # yet the axis never stops; after three cycles it holds 0.1 s at the top and goes on
    dt, step, amplitude, omega = 1e-3, 5e-9, 1e-6, 2 * np.pi
    cycles = amplitude * np.cos(omega * np.arange(3000) * dt)
    x = np.concatenate([cycles, np.full(100, amplitude), cycles[1:1000]])
    x = np.round(x / step) * step
    t = np.arange(x.size) * dt
    v = np.gradient(x, t)
    ctx = fx.Context.along(t, x, v, 0 * t, 0 * t, 5e-4, rest_band_m=1.5 * step)
    starts = np.flatnonzero((ctx.resting[1:] == 0.0) & (ctx.resting[:-1] == 1.0)) + 1
    # the record's own first rest (it began at rest), then the stop: no turnaround
    assert starts.size == 2
    assert t[starts[1]] == pytest.approx(3.1, abs=0.03)
    # the dwell: at least the hold, at most the hold and the 39 ms within the band at the top
    assert 0.1 <= ctx.dwell_s[starts[1]] <= 0.1 + 0.039


def test_settling_after_a_stop_is_not_a_start() -> None:
    # a stop that creeps by a few encoder steps over 10 ms, then rests 0.5 s: one rest
    dt, step = 1e-3, 5e-9
    t = np.arange(800) * dt
    x = np.concatenate([np.arange(100) * 1e-6, 99e-6 + step * np.minimum(np.arange(700), 4)])
    x = np.round(x / step) * step
    v = np.gradient(x, t)
    ctx = fx.Context.along(t, x, v, 0 * t, 0 * t, 5e-4, rest_band_m=1.5 * step)
    assert np.all(ctx.resting[110:] == 1.0)
    assert np.all(ctx.dwell_s[:] == 0.0)  # no start yet: no dwell ended


def test_ripple_coefficients_round_trip() -> None:
    e = fx.PositionRipple(1.5, 2.5e-3, 0.7)
    back = fx.PositionRipple.from_coefficients(e.coefficients(), e.shape())
    assert isinstance(back, fx.PositionRipple)
    assert back.amplitude_N == pytest.approx(1.5)
    assert back.phase_rad == pytest.approx(0.7)


def test_ripple_form_matches_spec() -> None:
    t = np.linspace(0, 1, 500)
    x = 0.01 * t
    ctx = _ctx(t, x, 0 * t)
    e = fx.PositionRipple(2.0, 2.5e-3, 0.3)
    np.testing.assert_allclose(
        e.apply(ctx, 0 * t), 2.0 * np.sin(2 * np.pi * x / 2.5e-3 + 0.3), atol=1e-12
    )


def test_stribeck_form_scales_the_gms_force() -> None:
    t = np.linspace(0, 1, 200)
    f = np.full_like(t, 10.0)
    ctx = fx.Context.along(t, 0 * t, np.full_like(t, 1e-3), 0 * t, f)
    out = fx.Stribeck(1.5, 1e-3).apply(ctx, f)
    np.testing.assert_allclose(out, 10.0 * (1 + 0.5 * math.exp(-1.0)))


def test_drift_limits() -> None:
    t = np.linspace(0, 100, 1000)
    f = np.full_like(t, 4.0)
    ctx = fx.Context.along(t, 1e-3 * t, np.full_like(t, 1e-3), 0 * t, f)
    out = fx.Drift(0.25, 5.0).apply(ctx, f)
    assert out[0] == pytest.approx(4.0)
    assert out[-1] == pytest.approx(5.0, rel=1e-6)


def test_reversal_transient_sign_and_decay() -> None:
    t, x = _triangle()
    ctx = _ctx(t, x, 0 * t)
    d = fx.ReversalTransient(3.0, 1e-5).apply(ctx, 0 * t)
    assert np.all(d * ctx.direction >= 0)  # overshoot along the motion
    s = ctx.distance_since_reversal_m
    assert np.all(d[np.isinf(s)] == 0.0)  # the first stroke follows no reversal
    first = int(np.flatnonzero(np.isfinite(s))[0])  # the first sample past the turn
    step = float(np.max(np.abs(np.diff(x))))
    assert 0.0 < s[first] <= step
    assert d[first] * ctx.direction[first] == pytest.approx(3.0 * math.exp(-s[first] / 1e-5))
    far = ctx.distance_since_reversal_m > 1e-4
    assert np.max(np.abs(d[far])) < 3.0 * math.exp(-10) * 1.01


def test_sensor_lowpass_keeps_dc_and_lags() -> None:
    t = np.arange(3000) * 1e-3
    ctx = _ctx(t, 1e-3 * np.sin(t))
    step = (t > 1.0).astype(float)
    y = fx.SensorLowpass(10.0, 2).apply(ctx, step)
    assert y[-1] == pytest.approx(1.0, abs=1e-6)
    assert y[1010] < 0.5  # a 10 Hz filter has not risen 10 ms after the step


@pytest.mark.parametrize(
    "effect",
    [fx.SensorLowpass(3.0, 1), fx.SensorLowpass(40.0, 2), fx.SensorLowpass(7.0, 3),
     fx.SensorLowpass(0.8, 4), fx.DriveLag(3e-4)],
)  # fmt: skip
def test_a_filter_of_many_columns_is_scipys_lfilter_of_each(effect: fx.FilterEffect) -> None:
    # the columns stepped together give scipy's numbers exactly (the same operations)
    rng = np.random.default_rng(3)
    x = np.cumsum(rng.normal(size=(4000, 7)), axis=0)
    b, a = effect.filter(1e-3)
    zi = signal.lfilter_zi(b, a)
    expected = signal.lfilter(b, a, x, axis=0, zi=np.multiply.outer(zi, x[0]))[0]
    assert np.array_equal(effect.filter_columns(x, 1e-3), expected)
    assert np.array_equal(effect.filter_columns(np.asfortranarray(x), 1e-3), expected)
    assert np.array_equal(effect.filter_columns(x[:, 2], 1e-3), expected[:, 2])


def test_dict_round_trip_and_bad_entries() -> None:
    for e in (fx.Viscous(12.0), fx.SensorLowpass(30.0, 2), fx.DwellTime(0.1, 1.0, 0.12)):
        assert fx.effect_from_dict(fx.effect_to_dict(e)) == e
    with pytest.raises(ValueError, match="unknown effect 'magic'"):
        fx.effect_from_dict({"effect": "magic", "parameters": {}})
    with pytest.raises(ValueError, match="parameters must be"):
        fx.effect_from_dict({"effect": "offset", "parameters": {"F0": 1.0}})
    with pytest.raises(ValueError, match="finite number"):
        fx.effect_from_dict({"effect": "offset", "parameters": {"offset_N": math.nan}})
    # a dwell gain's form at a turn: written, optional on reading (older tables: 0), 0 or 1
    kept = fx.DwellTime(0.1, 1.0, 0.12, 1.0)
    assert fx.effect_to_dict(kept)["parameters"]["kept_through_turns"] == 1.0
    assert fx.effect_from_dict(fx.effect_to_dict(kept)) == kept
    assert "kept_through_turns" not in fx.effect_to_dict(fx.DwellTime(0.1, 1.0, 0.12))["parameters"]
    params: dict[str, float] = {"gamma": 0.1, "tau_s": 1.0, "reach": 0.12}
    older = {"effect": "dwell_time", "parameters": params}
    assert fx.effect_from_dict(older) == fx.DwellTime(0.1, 1.0, 0.12, 0.0)
    params["kept_through_turns"] = 0.5
    with pytest.raises(fx.ExtensionError, match=r"kept_through_turns must be 0 or 1, got 0\.5"):
        fx.effect_from_dict(older)
    with pytest.raises(fx.ExtensionError, match=r"optional: \['kept_through_turns'\]"):
        fx.effect_from_dict({"effect": "dwell_time", "parameters": {"gamma": 0.1}})


def test_catalogue_names_match_spec() -> None:
    # the spec's catalogue plus two named extensions beyond it (EMPS)
    assert set(fx.CATALOGUE) == {
        "viscous", "stribeck", "dwell_time", "position_ripple", "offset",
        "reversal_transient", "drift", "inertia", "sensor_lowpass",
        "direction_asymmetry", "drive_lag",
    }  # fmt: skip


def test_drive_lag_is_a_first_order_lead() -> None:
    # command = force + lag dforce/dt: a ramp of slope 2 N/s gains 2 * lag once started
    t = np.arange(100) * 1e-3
    out = fx.DriveLag(5e-4).filter_columns(np.asarray(2.0 * t, dtype=np.float64), 1e-3)
    np.testing.assert_allclose(out[10:], 2.0 * t[10:] + 2.0 * 5e-4, atol=1e-12)


# the GMS a dwell gain raises (its force is not the context's here: the effect runs its own)
ELEMENTS = GmsParams(np.array([2e5, 1e6]), np.array([1.0, 4.0]), slip_level=1.2)
ALL = [
    fx.Viscous(30.0),
    fx.Stribeck(1.3, 2e-3),
    fx.DwellTime(0.2, 0.05, 0.25),
    fx.PositionRipple(0.5, 2.5e-4, 1.0),
    fx.Offset(-0.4),
    fx.ReversalTransient(0.8, 3e-5),
    fx.Drift(0.1, 0.5),
    fx.Inertia(2.0),
    fx.SensorLowpass(40.0, 2),
]


@settings(max_examples=15, deadline=None)
@given(st.integers(min_value=0, max_value=2**32 - 1))
def test_streaming_equals_batch(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 400
    t = np.arange(n) * 1e-3
    v = np.repeat(rng.normal(0, 2e-3, n // 40), 40) * (rng.random(n // 40).repeat(40) > 0.3)
    x = np.cumsum(v) * 1e-3
    a = np.gradient(v, t)
    f = np.tanh(x / 1e-5) * 5.0
    ctx = dataclasses.replace(fx.Context.along(t, x, v, a, f), gms=ELEMENTS)
    batch = fx.apply_extensions(ALL, ctx)
    stream = fx.ExtensionStream(ALL, 1e-3, gms=ELEMENTS)
    out = np.array([stream.step(t[i], x[i], v[i], a[i], f[i]) for i in range(n)])
    np.testing.assert_allclose(out, batch, rtol=1e-9, atol=1e-9)


def test_measurement_effects_are_flagged() -> None:
    # the compensator skips exactly the measurement chain (filters and the inertial force)
    flagged = {name for name, cls in fx.CATALOGUE.items() if cls.measurement_only}
    assert flagged == {"sensor_lowpass", "drive_lag", "inertia"}


def _slide_hold_slide(back: bool) -> tuple[np.ndarray, ...]:
    """0.1 ms samples: 30 um forward at 0.3 mm/s, 0.5 s at rest, then 30 um on (or back)."""
    v_move = np.full(1000, 3e-4)
    v = np.concatenate([v_move, np.zeros(5000), -v_move if back else v_move, np.zeros(500)])
    x = np.cumsum(v) * 1e-4
    t = np.arange(x.size) * 1e-4
    return t, x, v


@pytest.mark.parametrize("back", [False, True])
def test_dwell_gain_raises_one_element_by_gamma_log_of_the_dwell(back: bool) -> None:
    """One element of limit W = 2 N and break-away d = 4 um, C_v = 1: after 0.5 s at rest
    its limit is g W, g = 1 + gamma ln(1 + 0.5 / tau). Going on, it rests at W and
    stretches to g W before it slips (the plain one slides on at W): the extra force is a
    ramp of stiffness W / d up to (g - 1) W over (g - 1) d of travel, of area
    (g - 1)^2 W d / 2; going back, the plain one slips at -W after 2 d, the raised one at
    -g W after (1 + g) d: the same ramp, negative. The effect spreads the limit over
    break-aways d exp(+-SPREAD): the peak is at most (g - 1) W, reached within that
    spread, the area (g - 1)^2 W mean(d_j) / 2; after the widest has slipped, nothing."""
    t, x, v = _slide_hold_slide(back)
    w, d = 2.0, 4e-6
    gms = GmsParams(np.array([w / d]), np.array([w]))
    force = simulate(gms, x, v)[0]
    ctx = dataclasses.replace(fx.Context.along(t, x, v, 0 * t, force), gms=gms)
    gamma, tau = 0.2, 0.1
    g = 1.0 + gamma * math.log1p(0.5 / tau)
    extra = fx.DwellTime(gamma, tau, gamma).apply(ctx, force) - force
    assert ctx.dwell_s[-1] == pytest.approx(0.5, abs=1e-9)
    restart = 6000
    assert np.all(extra[:restart] == 0.0)  # nothing before the first standstill ends
    sign = -1.0 if back else 1.0
    travel = (np.arange(x.size) - restart + 1) * 3e-8
    spread = np.exp(np.linspace(-dwell_time.SPREAD, dwell_time.SPREAD, dwell_time.SPREAD_ELEMENTS))
    # sub-element j's window: from where the plain one slipped (0 going on, 2 d_j going
    # back) to where the raised one does ((g - 1) d_j, (1 + g) d_j)
    lo = 2.0 * d * spread[0] if back else (g - 1.0) * d * spread[0]
    hi = (1.0 + g if back else g - 1.0) * d * spread[-1]
    assert 0.0 < float(np.max(sign * extra)) <= (g - 1.0) * w + 1e-9
    assert lo - 3e-8 <= float(travel[np.argmax(sign * extra)]) <= hi + 3e-8
    area = float(np.sum(sign * extra) * 3e-8)
    assert area == pytest.approx((g - 1.0) ** 2 * w * d * np.mean(spread) / 2, rel=0.03)
    gone = travel > hi + 6e-8
    np.testing.assert_allclose(extra[gone], 0.0, atol=1e-9)  # slipped: the plain element


def test_a_dwell_gain_is_lost_where_the_move_turns_back_before_the_element_slips() -> None:
    """The element of the test above, 1 um on after the rest (less than the (g - 1) d =
    1.4 um of its raised window), then 3 um back: the extra force rises on the way out,
    and from the sample where the path's direction turns it is 0 (the raised element
    becomes the plain one), where a raised element that kept its stretch carried about
    k 1 um = 0.5 N on through the return."""
    w, d = 2.0, 4e-6
    step = 3e-8  # per 0.1 ms sample at 0.3 mm/s
    out, back = int(1e-6 / step), int(3e-6 / step)
    v = np.concatenate([np.full(1000, 3e-4), np.zeros(5000), np.full(out, 3e-4),
                        np.full(back, -3e-4), np.zeros(500)])  # fmt: skip
    x = np.cumsum(v) * 1e-4
    t = np.arange(x.size) * 1e-4
    gms = GmsParams(np.array([w / d]), np.array([w]))
    force = simulate(gms, x, v)[0]
    ctx = dataclasses.replace(fx.Context.along(t, x, v, 0 * t, force), gms=gms)
    extra = fx.DwellTime(0.2, 0.1, 0.2).apply(ctx, force) - force
    restart = 6000
    turned = restart + int(np.flatnonzero(ctx.direction[restart:] < 0.0)[0])
    assert restart + out <= turned <= restart + out + back // 2
    assert np.max(extra[restart:turned]) > 0.1  # the ramp on the way out
    assert np.all(extra[turned:] == 0.0)
