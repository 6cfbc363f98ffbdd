"""The diagnosis's kinematics at the ends of a trace: a trace that ends moving."""

from __future__ import annotations

import numpy as np
from scipy.integrate import cumulative_trapezoid

from gms_comp.measured.diagnosis.motion import kinematics
from gms_comp.measured.traces import Trace

RATE_HZ = 3600.0
STEP_M = 39e-9  # the encoder of independent none-107, which ends at 30.6 mm/s
ACCEL_CUTOFF_HZ = 245.0


def _ends_moving() -> tuple[Trace, np.ndarray]:
    """Rest, a raised-cosine acceleration to 30 mm/s over 50 ms, then that speed to the
    end; the encoder's position and the true acceleration."""
    t = np.arange(20_000) / RATE_HZ
    start, ramp, speed = 1.0, 0.05, 0.03
    u = np.clip((t - start) / ramp, 0.0, 1.0)
    accel = np.where((u > 0) & (u < 1), speed / ramp * (1 - np.cos(2 * np.pi * u)), 0.0)
    position = speed * ramp * (u**2 / 2 + (np.cos(2 * np.pi * u) - 1) / (4 * np.pi**2))
    position += speed * np.maximum(t - start - ramp, 0.0)
    quantised = np.round(position / STEP_M) * STEP_M
    return Trace("ends moving", t, quantised, np.zeros_like(t)), accel


def test_a_trace_that_ends_moving_has_no_acceleration_at_its_end() -> None:
    trace, accel = _ends_moving()
    kin = kinematics(trace, 0.45 * RATE_HZ, ACCEL_CUTOFF_HZ)
    peak = float(np.max(accel))  # 1.2 m/s^2
    interior = float(np.max(np.abs(kin.acceleration_m_s2 - accel)[200:-200]))
    end = float(np.max(np.abs(kin.acceleration_m_s2[-200:])))
    assert interior < 0.05 * peak
    assert end <= interior  # the end as good as the inside (analytic: 0)
    assert abs(float(np.mean(kin.velocity_m_s[-200:])) - 0.03) < 1e-6
    # MATLAB's 12-sample pad (the benchmark's kinematics) rings there
    benchmark = kinematics(trace, 0.45 * RATE_HZ, ACCEL_CUTOFF_HZ, reflected=False)
    assert float(np.max(np.abs(benchmark.acceleration_m_s2[-200:]))) > 0.5 * peak


def test_reflected_ends_change_the_acceleration_only_and_not_its_inside() -> None:
    trace, _ = _ends_moving()
    ours = kinematics(trace, 0.45 * RATE_HZ, ACCEL_CUTOFF_HZ)
    benchmark = kinematics(trace, 0.45 * RATE_HZ, ACCEL_CUTOFF_HZ, reflected=False)
    # position and velocity keep the benchmark's edges, bit for bit, ends included
    assert np.array_equal(ours.position_m, benchmark.position_m)
    assert np.array_equal(ours.velocity_m_s, benchmark.velocity_m_s)
    # inside, only the second difference's width differs (three samples, not five):
    # under 0.1 % of the 1.2 m/s^2 peak on a 50 ms ramp
    inside = slice(500, -500)
    np.testing.assert_allclose(
        ours.acceleration_m_s2[inside], benchmark.acceleration_m_s2[inside], atol=1e-3
    )
    assert not np.allclose(ours.acceleration_m_s2[-20:], benchmark.acceleration_m_s2[-20:])
    assert ours.acceleration_m_s2.shape == trace.position_m.shape


def _fast_ramps(rate_Hz: float, ramp_s: float) -> tuple[Trace, np.ndarray]:
    """Back-and-forth moves whose raised-cosine acceleration pulses last ``ramp_s`` (a few
    samples at ``rate_Hz``), the position integrated on a 50 x finer grid and read by a
    5 nm encoder; the trace and the true acceleration at its samples."""
    fine = 50
    t_fine = np.arange(4000 * fine) / (rate_Hz * fine)
    accel_fine = np.zeros_like(t_fine)
    for k in range(8):
        u = np.clip((t_fine - 0.5 - 0.4 * k) / ramp_s, 0.0, 1.0)
        accel_fine += (-1) ** k * np.where((u > 0) & (u < 1), 5.0 * (1 - np.cos(2 * np.pi * u)), 0)
    velocity = cumulative_trapezoid(accel_fine, t_fine, initial=0.0)
    position = cumulative_trapezoid(velocity, t_fine, initial=0.0)[::fine]
    t = t_fine[::fine]
    quantised = np.round(position / 5e-9) * 5e-9
    return Trace("fast ramps", t, quantised, np.zeros_like(t)), accel_fine[::fine]


def test_a_mass_fitted_on_short_ramps_is_not_biased_by_the_difference() -> None:
    # independent inertia-239 (1 kHz, half its acceleration's energy above 50 Hz): the
    # mass came out 16 % high on the benchmark's five-sample second difference
    rate = 1000.0
    trace, accel = _fast_ramps(rate, 0.008)

    def fitted_over_true(kin_accel: np.ndarray) -> float:  # F = m a fitted on the estimate
        return float(np.dot(kin_accel, accel) / np.dot(kin_accel, kin_accel))

    diagnosis = kinematics(trace, 0.45 * rate, 0.45 * rate).acceleration_m_s2
    benchmark = kinematics(trace, 0.45 * rate, 0.45 * rate, reflected=False).acceleration_m_s2
    assert abs(fitted_over_true(diagnosis) - 1.0) < 0.03
    assert fitted_over_true(benchmark) > 1.05  # sinc(2 f dt)^2: what the old column lost
