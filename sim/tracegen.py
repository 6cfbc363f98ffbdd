"""Measured-like traces with a hidden effect, for blind tests of the diagnosis.

The truth is a GMS friction model (the project's kernel, :mod:`gms_comp.gms`) run along
an identification trajectory; one catalogue effect (or none) drawn at random is applied
with :mod:`gms_comp.effects`, then sensor noise and the quantisation of an encoder and a
force ADC. The effect sizes are drawn in ranges that matter for compensation (a tenth to
a third of the sliding force), not at the edge of detectability.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from gms_comp import effects as fx
from gms_comp.gms import GmsParams, simulate
from gms_comp.traces import Trace

FloatArray = NDArray[np.float64]

# The main parameter of each spec catalogue effect, as the diagnosis must recover it.
MAIN_PARAMETER = {
    "viscous": "c_Ns_per_m",
    "stribeck": "ratio",
    "dwell_time": "gamma",
    "position_ripple": "wavelength_m",
    "offset": "offset_N",
    "reversal_transient": "amplitude_N",
    "drift": "kappa",
    "inertia": "mass_kg",
    "sensor_lowpass": "cutoff_Hz",
}
HIDDEN_CHOICES = (*MAIN_PARAMETER, "none")

TRUTH_GMS = GmsParams(
    stiffness_N_per_m=np.array([4.0, 3.0, 2.5, 2.0, 1.5])
    / np.array([0.3e-6, 1e-6, 3e-6, 8e-6, 20e-6]),
    limit_N=np.array([4.0, 3.0, 2.5, 2.0, 1.5]),
)
TRUTH_PRESLIDING_M = 20e-6
GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def identification_profile(
    sample_rate_Hz: float = 1000.0, scale: float = 1.0
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
        n = max(2, round(abs(dx) / speed / dt))
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
class GeneratedTrace:
    trace: Trace
    hidden: fx.Effect | None
    force_kind: str


def draw_effect(
    name: str, rng: np.random.Generator, t: FloatArray, v: FloatArray
) -> fx.Effect | None:
    """One effect of the catalogue with parameters drawn in a range that matters."""
    level = float(np.sum(TRUTH_GMS.limit_N))
    vmax = float(np.max(np.abs(v)))
    amax = float(np.max(np.abs(np.gradient(v, t))))
    u = rng.uniform
    if name == "none":
        return None
    effects: dict[str, fx.Effect] = {
        "viscous": fx.Viscous(u(0.15, 0.4) * level / vmax),
        "stribeck": fx.Stribeck(u(1.3, 1.8), u(0.05, 0.2) * vmax),
        "dwell_time": fx.DwellTime(u(0.15, 0.3), u(0.01, 0.05), TRUTH_PRESLIDING_M),
        "position_ripple": fx.PositionRipple(
            u(0.08, 0.2) * level, u(0.5e-3, 3e-3), u(-math.pi, math.pi)
        ),
        "offset": fx.Offset(float(rng.choice([-1, 1])) * u(0.08, 0.2) * level),
        "reversal_transient": fx.ReversalTransient(u(0.15, 0.3) * level, u(20e-6, 80e-6)),
        "drift": fx.Drift(u(0.15, 0.3), u(0.1, 0.4) * float(t[-1])),
        "inertia": fx.Inertia(u(0.3, 0.6) * level / amax),
        "sensor_lowpass": fx.SensorLowpass(u(5.0, 25.0), int(rng.integers(1, 3))),
    }
    return effects[name]


def generate(
    hidden: str,
    seed: int,
    scale: float = 0.5,
    sample_rate_Hz: float = 1000.0,
    noise_fraction: float = 0.01,
    position_resolution_m: float = 1e-7,
) -> GeneratedTrace:
    """A friction-force trace of the truth model with the effect ``hidden`` (or "none")."""
    if hidden not in HIDDEN_CHOICES:
        raise ValueError(f"unknown hidden effect {hidden!r}")
    rng = np.random.default_rng(seed)
    t, x, v = identification_profile(sample_rate_Hz, scale)
    a = np.gradient(v, t)
    gms_force = simulate(TRUTH_GMS, x, v)[0]
    effect = draw_effect(hidden, rng, t, v)
    extensions = [] if effect is None else [effect]
    ctx = fx.Context.along(t, x, v, a, gms_force, 0.01 * float(np.max(np.abs(v))))
    force = fx.apply_extensions(extensions, ctx)
    level = float(np.sum(TRUTH_GMS.limit_N))
    force = force + rng.normal(0.0, noise_fraction * level, force.size)
    adc_step = level / 4000  # a 12-bit force channel over +-2x the sliding force
    force = np.round(force / adc_step) * adc_step
    measured_x = np.round(x / position_resolution_m) * position_resolution_m
    trace = Trace(
        source=f"tracegen:{hidden}:{seed}", time_s=t, position_m=measured_x, force_N=force
    )
    return GeneratedTrace(trace, effect, "friction")


def scaled_table_trace(
    table: GmsParams, level: float, presliding: float, seed: int, scale: float = 0.5
) -> Trace:
    """A friction trace of ``table`` with its level and presliding length scaled, over the
    identification profile, with 1 % noise and 0.1 um position steps: a machine whose
    guides match the catalogue table up to the three factors a calibration must find."""
    from gms_comp.diagnosis.baseline import scaled  # the diagnosis's own definition of the factors

    t, x, v = identification_profile(1000.0, scale)
    truth = scaled(table, level, presliding)
    force = simulate(truth, x, v)[0]
    noise = 0.01 * float(np.sum(truth.limit_N))
    force = force + np.random.default_rng(seed).normal(0.0, noise, force.size)
    return Trace(source="scaled table", time_s=t, position_m=np.round(x, 7), force_N=force)
