"""The GMS truth of simulated measured traces: an identification trajectory and the
friction force of a GMS along it, then the sensors (noise, encoder and ADC steps).

Only the runtime's GMS kernel (:mod:`gms_comp.gms`) is used here: catalogue effects are
applied at the application level (``gms-comp demo-trace``,
:mod:`gms_comp.app.commands.demo_trace`), and the blind tests of the diagnosis use an
independent generator (tests/indepgen.py) that shares no code with the project.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.gms import GmsParams, simulate

TRUTH_GMS = GmsParams(
    stiffness_N_per_m=np.array([4.0, 3.0, 2.5, 2.0, 1.5])
    / np.array([0.3e-6, 1e-6, 3e-6, 8e-6, 20e-6]),
    limit_N=np.array([4.0, 3.0, 2.5, 2.0, 1.5]),
)
TRUTH_PRESLIDING_M = 20e-6
GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def identification_profile(
    sample_rate_Hz: float = 1000.0, scale: float = 1.0, max_acceleration_m_s2: float | None = None
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """A recommended identification trajectory ``(t_s, x_m, v_m_s)``.

    Parts: the seed's step-and-stop (0.1 mm steps at 10 mm/s) with dwell times spread
    log-uniformly from 2 ms to 2 s, strokes of 20 mm at 5, 20 and 50 mm/s, and presliding
    cycles of 2-50 um. ``scale`` < 1 shortens it for quick tests (fewer steps and cycles).
    The dwells span three decades around the 10-50 ms time constants of a dwell gain
    1 + gamma ln(1 + t_d/tau): with 10 ms to 1 s only, gamma and tau trade off (the
    diagnosis found gamma 20-37 % and tau about 2x too high, their product right).
    """
    dt = 1.0 / sample_rate_Hz
    segments: list[FloatArray] = []
    x = 0.0

    def move(dx: float, speed: float) -> None:
        nonlocal x
        duration = abs(dx) / speed
        if max_acceleration_m_s2 is not None:  # a cosine ramp peaks at pi^2 dx / (2 T^2)
            duration = max(duration, math.pi * math.sqrt(abs(dx) / (2 * max_acceleration_m_s2)))
        n = max(2, round(duration / dt))
        ramp = 0.5 - 0.5 * np.cos(np.linspace(0, np.pi, n + 1)[1:])  # smooth start and stop
        segments.append(x + dx * ramp)
        x += dx

    def dwell(duration_s: float) -> None:
        segments.append(np.full(max(1, round(duration_s / dt)), x))

    n_steps = max(4, round(16 * scale))
    dwells = np.geomspace(0.002, 2.0, n_steps)
    # shuffled (golden-ratio order), so a dwell's length does not follow from its place
    order = np.argsort((np.arange(n_steps) * GOLDEN) % 1.0)
    for sign in (1.0, -1.0):
        for k in order:
            move(sign * 1e-4, 0.01)
            dwell(float(dwells[k]))
    for speed in (0.005, 0.02, 0.05):
        for _ in range(max(1, round(2 * scale))):
            move(0.02, speed)
            dwell(0.05)
            move(-0.02, speed)
            dwell(0.05)
    for amp in np.geomspace(2e-6, 5e-5, max(3, round(6 * scale))):
        speed = amp / 0.1  # each stroke takes 0.1 s: well inside any position filter
        for _ in range(2):
            move(amp, speed)
            move(-2 * amp, speed)
            move(amp, speed)
    xs = np.concatenate([[0.0], *segments]).astype(np.float64)
    t = np.arange(xs.size, dtype=np.float64) * dt
    return t, xs, np.asarray(np.gradient(xs, dt), dtype=np.float64)


@dataclass(frozen=True)
class Truth:
    """A trajectory and the truth GMS's friction force along it (SI units)."""

    time_s: FloatArray
    position_m: FloatArray
    velocity_m_s: FloatArray
    acceleration_m_s2: FloatArray
    gms_force_N: FloatArray
    sliding_force_N: float


def truth(
    params: GmsParams = TRUTH_GMS, scale: float = 0.5, sample_rate_Hz: float = 1000.0
) -> Truth:
    """The friction force of ``params`` along :func:`identification_profile`."""
    t, x, v = identification_profile(sample_rate_Hz, scale)
    # the acceleration the hidden inertia acts on: the three-point second difference of
    # the sampled position, a convention (each move's acceleration jumps at its start and
    # stop) that the diagnosis shares, so the inertia case here checks the fit, not the
    # difference; the difference itself is checked against a continuous truth in
    # tests/test_motion_edges.py
    a = np.zeros_like(x)
    a[1:-1] = (x[2:] - 2.0 * x[1:-1] + x[:-2]) / (t[1] - t[0]) ** 2
    force = simulate(params, x, v)[0]
    return Truth(t, x, v, a, force, float(np.sum(params.limit_N)) * params.slip_level)


def measure(
    force_N: FloatArray, position_m: FloatArray, level_N: float, rng: np.random.Generator,
    noise_fraction: float = 0.01, position_resolution_m: float = 1e-7,
) -> tuple[FloatArray, FloatArray]:  # fmt: skip
    """What the sensors report: the force with white noise of ``noise_fraction`` x
    ``level_N`` and a 12-bit ADC over +-2x the level, the position on encoder steps."""
    noisy = force_N + rng.normal(0.0, noise_fraction * level_N, force_N.size)
    adc_step = level_N / 4000
    return (
        np.round(noisy / adc_step) * adc_step,
        np.round(position_m / position_resolution_m) * position_resolution_m,
    )
