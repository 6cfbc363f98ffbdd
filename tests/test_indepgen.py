"""Sanity tests of the independent trace generator itself (analytic cases, effect forms)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from indepgen import (
    CASES,
    CATALOGUE,
    MAIN_PARAMETER,
    PAIR_SIZE_RATIO,
    PAIRS,
    Truth,
    baseline,
    dwell_gain,
    friction,
    make_trace,
    median_standstill,
    parameter_error,
    play_operator,
    velocity_level,
    write_csv,
)
from scipy import signal

SHORT = 60_000
FORM_SEED = 11  # its first 60 000 samples (40 s at 1.5 kHz) hold every family, up to 98 mm/s


def _path(*points_m: float, step_m: float = 1e-8) -> np.ndarray:
    """Position increments of a piecewise-linear path through ``points_m`` (from 0)."""
    legs = [
        np.linspace(a, b, round(abs(b - a) / step_m) + 1)[1:]
        for a, b in zip((0.0, *points_m[:-1]), points_m, strict=True)
    ]
    return np.diff(np.concatenate([[0.0], *legs]), prepend=0.0)


def _constant(n: int) -> np.ndarray:
    return np.ones(n)


def test_single_element_virgin_curve_and_reversal_slope() -> None:
    k, breakaway = 2.0e5, 10e-6  # limit 2 N
    dx = _path(30e-6, 10e-6)
    force = play_operator(dx, np.array([k]), np.array([breakaway]), _constant(dx.size))
    x = np.cumsum(dx)
    virgin = slice(0, 3000)
    np.testing.assert_allclose(force[virgin], np.minimum(k * x[virgin], k * breakaway), atol=1e-9)
    back = x[3000:] - 30e-6  # negative travel after the reversal
    np.testing.assert_allclose(force[3000:], k * breakaway + k * back, atol=1e-9)


def test_single_element_saturates_at_its_limit_both_ways() -> None:
    dx = _path(50e-6, -50e-6)
    force = play_operator(dx, np.array([1e5]), np.array([5e-6]), _constant(dx.size))
    assert force.max() == pytest.approx(0.5, abs=1e-12)
    assert force.min() == pytest.approx(-0.5, abs=1e-12)


def test_hysteresis_loop_area_is_four_limit_times_amplitude_less_breakaway() -> None:
    stiffness = np.array([4e5, 1e5, 2e4])
    breakaway = np.array([0.5e-6, 3e-6, 25e-6])
    amplitude = 10e-6  # the third element never slips: it adds no area
    dx = _path(amplitude, -amplitude, amplitude, -amplitude, amplitude)
    force = play_operator(dx, stiffness, breakaway, _constant(dx.size))
    x = np.cumsum(dx)
    loop = slice(np.flatnonzero(np.isclose(x, amplitude, atol=1e-12, rtol=0))[-2], None)
    area = np.trapezoid(force[loop], x[loop])  # down on the lower branch, up on the upper
    expected = np.sum(4 * stiffness * breakaway * np.clip(amplitude - breakaway, 0, None))
    assert area == pytest.approx(expected, rel=1e-3)


def test_break_away_gain_makes_a_peak_that_is_lost_once_the_element_slips() -> None:
    k, breakaway, gain = 1e5, 10e-6, 1.3
    dx = _path(30e-6, 60e-6)
    boost = np.ones(dx.size)
    boost[3000] = gain  # restart after a standstill
    force = play_operator(dx, np.array([k]), np.array([breakaway]), _constant(dx.size), boost)
    assert force[:3000].max() == pytest.approx(k * breakaway, rel=1e-12)
    assert force[3000:].max() == pytest.approx(gain * k * breakaway, rel=1e-3)
    assert force[-1] == pytest.approx(k * breakaway, rel=1e-12)


def _sliding_truth(speed_m_s: float, rate_Hz: float = 2000.0) -> Truth:
    velocity = np.concatenate([np.full(2000, speed_m_s), np.zeros(500)])
    position = np.cumsum(velocity) / rate_Hz
    return Truth(
        stiffness_N_per_m=np.array([5e6, 1e6, 1e5]),
        breakaway_m=np.array([0.3e-6, 2e-6, 20e-6]),
        C_v=1.2,
        transition_velocity_m_per_s=0.3e-3,
        sample_rate_Hz=rate_Hz,
        time_s=np.arange(velocity.size) / rate_Hz,
        position_m=position,
        velocity_m_s=velocity,
        acceleration_m_s2=np.gradient(velocity) * rate_Hz,
    )


def test_steady_sliding_reaches_C_v_times_stick_and_drops_back_at_a_stop() -> None:
    truth = _sliding_truth(20e-3)
    stick = float(np.sum(truth.stiffness_N_per_m * truth.breakaway_m))
    force = friction(truth, ())
    level_at_speed = velocity_level(np.array([20e-3]), 1.2, 0.3e-3)[0]
    assert force[1500] == pytest.approx(stick * level_at_speed, rel=1e-12)
    assert level_at_speed == pytest.approx(1.2, rel=1e-3)
    assert force[-1] == pytest.approx(stick, rel=1e-12)
    assert truth.sliding_force_N == pytest.approx(1.2 * stick)


def test_friction_opposes_the_motion() -> None:
    gen = make_trace("none", 5, SHORT)
    speed = np.gradient(gen.position_m, gen.time_s)
    fast = np.abs(speed) > 5e-3
    assert np.mean(np.sign(gen.force_N[fast]) == np.sign(speed[fast])) > 0.98


@pytest.mark.parametrize("seed", [0, 1])
def test_nominal_ranges_of_the_default_trace(seed: int) -> None:
    gen = make_trace("none", seed)
    assert 100_000 <= gen.time_s.size <= 200_000
    assert 1.0 <= gen.C_v <= 1.3 and 3 <= gen.n_elements <= 12
    assert 1000 <= gen.sample_rate_Hz <= 5000
    assert 0.005 <= gen.noise_N / gen.sliding_force_N <= 0.03
    assert 1e-9 <= gen.quantisation_m <= 50e-9
    assert 3.0 <= gen.sliding_force_N <= 40.0 * 1.3
    steps = np.diff(gen.position_m) / gen.quantisation_m
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-3)
    speed = np.abs(np.gradient(gen.position_m, gen.time_s))
    assert np.max(speed) > 20e-3 and np.mean(speed == 0.0) > 0.1  # fast moves and standstills
    reversals = np.sum(np.diff(np.sign(np.diff(gen.position_m))[np.diff(gen.position_m) != 0]) != 0)
    assert reversals > 20


def test_same_seed_same_trace_and_another_seed_another() -> None:
    a, b, c = (
        make_trace("viscous", 3, SHORT),
        make_trace("viscous", 3, SHORT),
        make_trace("viscous", 4, SHORT),
    )
    np.testing.assert_array_equal(a.force_N, b.force_N)
    np.testing.assert_array_equal(a.position_m, b.position_m)
    assert a.effects == b.effects
    assert not np.array_equal(a.force_N[:1000], c.force_N[:1000])


def _difference(
    case: str, seed: int = FORM_SEED
) -> tuple[np.ndarray, dict[str, float], np.ndarray]:
    """Force of ``case`` minus the effect-free force of the same seed (noise cancels)."""
    with_effect, without = make_trace(case, seed, SHORT), make_trace("none", seed, SHORT)
    np.testing.assert_array_equal(with_effect.position_m, without.position_m)
    return with_effect.force_N - without.force_N, with_effect.effects[0][1], without.force_N


def _smooth(values: np.ndarray, deriv: int = 0) -> np.ndarray:
    """Savitzky-Golay over 20 ms of the form-test trace (its sample rate is 1.5 kHz)."""
    return signal.savgol_filter(values, 31, 3, deriv=deriv, delta=1 / 1500.0)


def _smooth_derivatives(gen_seed: int = FORM_SEED) -> tuple[np.ndarray, np.ndarray]:
    """Speed and acceleration estimated from the quantised measured position."""
    gen = make_trace("none", gen_seed, SHORT)
    assert gen.sample_rate_Hz == 1500.0
    return _smooth(gen.position_m, 1), _smooth(gen.position_m, 2)


def test_offset_shifts_the_force_by_offset_N() -> None:
    diff, p, _ = _difference("offset")
    np.testing.assert_allclose(diff, p["offset_N"], atol=1e-9)


def test_viscous_and_inertia_follow_the_measured_position() -> None:
    speed, accel = _smooth_derivatives()
    diff, p, _ = _difference("viscous")
    slope = np.dot(_smooth(diff), speed) / np.dot(speed, speed)
    assert slope == pytest.approx(p["c_Ns_per_m"], rel=0.02)
    diff, p, _ = _difference("inertia")
    slope = np.dot(_smooth(diff), accel) / np.dot(accel, accel)
    assert slope == pytest.approx(p["mass_kg"], rel=0.05)


def test_ripple_has_its_wavelength_in_the_spectrum_against_position() -> None:
    diff, p, _ = _difference("position_ripple")
    x = make_trace("none", FORM_SEED, SHORT).position_m
    wavelengths = np.geomspace(0.3e-3, 15e-3, 400)
    power = signal.lombscargle(x, diff, 2 * np.pi / wavelengths)
    assert wavelengths[np.argmax(power)] == pytest.approx(p["wavelength_m"], rel=0.02)
    assert np.max(np.abs(diff)) == pytest.approx(abs(p["amplitude_N"]), rel=0.01)


def test_reversal_transient_peaks_at_amplitude_in_the_new_direction() -> None:
    diff, p, _ = _difference("reversal_transient")
    speed, _ = _smooth_derivatives()
    assert np.max(np.abs(diff)) == pytest.approx(p["amplitude_N"], rel=0.02)
    acting = (np.abs(speed) > 1e-3) & (np.abs(diff) > 0.01 * p["amplitude_N"])
    assert np.mean(np.sign(diff[acting]) == np.sign(speed[acting])) > 0.95


def test_drift_scales_the_friction_towards_one_plus_kappa() -> None:
    diff, p, base = _difference("drift")
    t = make_trace("none", FORM_SEED, SHORT).time_s
    scale = p["kappa"] * -np.expm1(-t / p["tau_s"])
    assert np.dot(diff, scale * base) / np.dot(scale * base, scale * base) == pytest.approx(
        1.0, rel=0.02
    )


def test_sensor_lowpass_attenuates_by_a_half_power_at_its_cutoff() -> None:
    gen = make_trace("sensor_lowpass", FORM_SEED, SHORT)
    p = gen.effects[0][1]
    raw = make_trace("none", FORM_SEED, SHORT).force_N
    # raw = clean + noise, filtered = H clean + noise: their difference is (H - 1) clean
    f, pxy = signal.csd(raw, gen.force_N - raw, fs=gen.sample_rate_Hz, nperseg=4096)
    _, pxx = signal.welch(raw, fs=gen.sample_rate_Hz, nperseg=4096)
    gain = np.abs(1.0 + pxy / pxx)
    assert np.interp(p["cutoff_Hz"], f, gain) == pytest.approx(2**-0.5, rel=0.15)
    assert np.interp(0.2 * p["cutoff_Hz"], f, gain) == pytest.approx(1.0, abs=0.1)


def test_stribeck_raises_friction_at_low_speed_only() -> None:
    diff, p, _ = _difference("stribeck")
    speed, _ = _smooth_derivatives()
    fast = np.abs(speed) > 3 * p["v_s_m_per_s"]
    assert fast.sum() > 100
    assert np.max(np.abs(diff[fast])) < 0.02 * np.max(np.abs(diff))
    assert np.max(np.abs(diff)) > 0.1 * np.max(np.abs(make_trace("none", FORM_SEED, SHORT).force_N))


def _level_change(case: str, p: dict[str, float], x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The documented factor on the limits, minus one, written out again here."""
    if case == "unknown_stroke_profile":
        return p["beta"] * ((x - p["centre_m"]) / p["half_stroke_m"]) ** 2
    if case == "unknown_bumps":
        centres = [v for k, v in p.items() if k.startswith("position_m_")]
        bumps = np.exp(-(((x[:, None] - np.array(centres)) / p["width_m"]) ** 2))
        return p["height"] * bumps.sum(axis=1)
    return p["beta"] * np.sin(2 * np.pi * p["frequency_Hz"] * t + p["phase_rad"])


@pytest.mark.parametrize(
    "case", ["unknown_stroke_profile", "unknown_bumps", "unknown_time_modulation"]
)
def test_uncatalogued_effects_scale_the_sliding_level(case: str) -> None:
    diff, p, base = _difference(case)
    gen = make_trace("none", FORM_SEED, SHORT)
    speed, _ = _smooth_derivatives()
    sliding = np.abs(speed) > 2e-3
    expected = (_level_change(case, p, gen.position_m, gen.time_s) * base)[sliding]
    assert np.std(expected) > 0.03 * gen.sliding_force_N
    slope = np.dot(diff[sliding], expected) / np.dot(expected, expected)
    assert slope == pytest.approx(1.0, abs=0.1)


@pytest.mark.parametrize(("big", "small"), PAIRS)
def test_pairs_have_a_clearly_larger_effect(big: str, small: str) -> None:
    gen = make_trace(f"pair_{big}_{small}", 2, SHORT)
    assert [name for name, _ in gen.effects] == [big, small] and gen.expected == big
    truth = baseline(2, SHORT)[0]
    plain = friction(truth, ())
    rms = [np.sqrt(np.mean((friction(truth, (e,)) - plain) ** 2)) for e in gen.effects]
    assert rms[0] / rms[1] == pytest.approx(PAIR_SIZE_RATIO, rel=0.02)


def test_catalogue_cases_name_their_effect_and_parameters() -> None:
    assert set(MAIN_PARAMETER) == set(CATALOGUE) and len(set(CASES)) == len(CASES)
    gen = make_trace("stribeck", 1, SHORT)
    name, p = gen.effects[0]
    assert gen.expected == name == "stribeck" and p["ratio"] > 1.0
    assert parameter_error(
        "stribeck", p, {"ratio": 1.0 + 1.1 * (p["ratio"] - 1.0)}
    ) == pytest.approx(0.1)


def test_csv_round_trip(tmp_path: Path) -> None:
    gen = make_trace("offset", 1, 5000)
    path = write_csv(gen, tmp_path / "trace.csv")
    assert path.read_text().splitlines()[0] == "time_s,position_m,force_N"
    table = np.loadtxt(path, delimiter=",", skiprows=1)
    np.testing.assert_allclose(table[:, 0], gen.time_s, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(table[:, 1], gen.position_m, rtol=1e-11, atol=1e-15)
    np.testing.assert_allclose(table[:, 2], gen.force_N, rtol=1e-8)
    assert not list(tmp_path.glob(".*partial"))


def test_a_dwell_gain_is_judged_at_the_median_standstill() -> None:
    # gamma and tau that give the same gain after the trace's median standstill are one
    # answer (the trace cannot tell them apart); a gain 10 % off there is 10 % off
    gen = make_trace("dwell_time", 1, SHORT)
    p = gen.effects[0][1]
    median = median_standstill(baseline(1, SHORT)[0])
    assert p["median_standstill_s"] == median > 0.0
    size = dwell_gain(p, median)
    tau = 3.0 * p["tau_s"]
    same = {"gamma": size / np.log1p(median / tau), "tau_s": tau}
    assert parameter_error("dwell_time", p, same) == pytest.approx(0.0, abs=1e-12)
    assert abs(same["gamma"] / p["gamma"] - 1.0) > 0.5  # gamma alone: far off
    more = {"gamma": 1.1 * p["gamma"], "tau_s": p["tau_s"]}
    assert parameter_error("dwell_time", p, more) == pytest.approx(0.1)


def test_low_passed_noise_keeps_its_standard_deviation_and_loses_its_high_frequencies() -> None:
    white = make_trace("none", FORM_SEED, SHORT)
    coloured = make_trace("none", FORM_SEED, SHORT, noise_cutoff_Hz=75.0)  # 1.5 kHz / 20
    # the same truth: the two differ by the noise only (white out, low-passed in)
    truth = white.force_N - baseline(FORM_SEED, SHORT)[3]
    low = coloured.force_N - truth
    assert np.std(low) == pytest.approx(white.noise_N, rel=1e-6)
    # a 2nd-order 75 Hz filter at 1.5 kHz: its sample-to-sample differences a small share
    assert np.std(np.diff(low)) < 0.3 * np.std(np.diff(white.force_N - truth))
