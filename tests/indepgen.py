"""An independent generator of measured-like friction traces, for blind tests of the diagnosis.

Written from the specs only (``measured-data.md``'s catalogue, ``physics.md``, the seed paper)
and sharing no code with ``gms_comp`` or ``sim``: numpy/scipy only, its own play operator,
its own trajectories (``indepmotion``), its own nominal ranges.

Truth
-----
(``indepfriction``) A plain Maxwell-slip model of N = 3-12 elements, break-away displacements spread
log-uniformly over 0.2-30 um, sliding level 3-40 N. The element limits rise with speed from
the stick level to C_v (1.0-1.3) times it, smoothly, over a transition velocity v_t of
0.1-0.8 mm/s: limit factor 1 + (C_v - 1) q / (1 + q), q = (|v| / v_t)^2. This is the seed's
slip level above stick and belongs to the baseline (a trace with only it is ``none``).
Friction is positive when the carriage moves in +x (the force needed to push it).

Measurement: white force noise (low-passed on request) of 0.5-3 % of the sliding level,
sample rate 1-5 kHz, position quantised to 1-50 nm. Effects (the catalogue's forms and
parameter names) are drawn at sizes that matter for compensation (about 10-30 % of the
sliding force or the equivalent).

Uncatalogued effects (the diagnosis must answer ``unknown``); each one is odd in the
direction of motion (it acts on the friction level), so neither ``offset`` nor
``position_ripple`` (both even in direction) can carry it, and it is not a function of
speed, dwell, reversal distance or acceleration, so no other entry can either:

- ``unknown_stroke_profile``: the element limits grow as 1 + beta u^2 with the distance u
  from the stroke centre (a crowned rail, a preload that rises towards the ends).
- ``unknown_bumps``: the limits rise by a Gaussian bump at 2-4 discrete positions (dirt,
  a damaged raceway spot): localised in position, not periodic.
- ``unknown_time_modulation``: the limits are modulated periodically in time at
  0.05-0.3 Hz, at least four periods per trace (a periodic load or temperature cycle),
  unrelated to position or motion; ``drift`` is monotonic in time and cannot follow it.

Pairs (``pair_<larger>_<smaller>``): two catalogue effects at once; the smaller one's force
contribution (RMS over the trace) is a third of the larger one's, so the ranking is defined.

Trajectory (``indepmotion``): shuffled cycles of the seed's step-and-stop (0.05-0.2 mm steps,
dwells 0.05-3 s), S-curve point-to-point moves (slow, medium and fast within 1-100 mm/s),
sines (0.05-5 mm, 1-100 mm/s peak) and micrometre reversals (1-20 um), from rest to rest.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from indepfriction import Effect, Truth, friction, play_operator, velocity_level
from indepmotion import trajectory
from scipy import signal

__all__ = [
    "CASES",
    "CATALOGUE",
    "MAIN_PARAMETER",
    "PAIRS",
    "UNKNOWN",
    "Generated",
    "Truth",
    "baseline",
    "dwell_gain",
    "friction",
    "make_trace",
    "median_standstill",
    "parameter_error",
    "play_operator",
    "velocity_level",
    "with_effect",
    "write_csv",
]

CATALOGUE = (
    "viscous",
    "stribeck",
    "dwell_time",
    "position_ripple",
    "offset",
    "reversal_transient",
    "drift",
    "inertia",
    "sensor_lowpass",
)
# The fitted parameter each effect is judged by (dwell_time: gamma and tau_s, through the
# gain after the median standstill; see parameter_error).
MAIN_PARAMETER = {
    "viscous": "c_Ns_per_m",
    "stribeck": "ratio",
    "dwell_time": "gamma",
    "position_ripple": "amplitude_N",
    "offset": "offset_N",
    "reversal_transient": "amplitude_N",
    "drift": "kappa",
    "inertia": "mass_kg",
    "sensor_lowpass": "cutoff_Hz",
}
UNKNOWN = ("unknown_stroke_profile", "unknown_bumps", "unknown_time_modulation")
# (larger, smaller): the larger one is drawn at the size given here (a fraction of the sliding
# level, in its own terms), then the smaller one's main parameter is scaled so that its force
# contribution's RMS over the trace is a third of the larger one's. The larger ones are
# effects present all along the trace, so the smaller one stays well above the noise.
PAIR_SIZES = {
    ("offset", "viscous"): 0.15,
    ("drift", "offset"): 0.3,
    ("position_ripple", "inertia"): 0.3,
    ("offset", "stribeck"): 0.3,
    ("drift", "reversal_transient"): 0.3,
}
PAIRS = tuple(PAIR_SIZES)
CASES = ("none", *CATALOGUE, *UNKNOWN, *(f"pair_{a}_{b}" for a, b in PAIRS))
PAIR_SIZE_RATIO = 3.0


@dataclass(frozen=True, eq=False)
class Generated:
    """One generated trace with its truth.

    Attributes
    ----------
    case, seed : str, int
        What was asked for.
    time_s, position_m, force_N : numpy.ndarray
        The measured trace (quantised position, noisy force).
    effects : tuple of (name, parameters)
        The hidden effects, largest first, spec parameter names, SI units.
    expected : str
        The name a correct diagnosis gives first: a catalogue name, ``none`` or ``unknown``.
    C_v, transition_velocity_m_per_s : float
        The baseline's slip level above stick and the speed over which it is reached.
    n_elements : int
        Maxwell-slip elements of the truth.
    sliding_force_N, noise_N, sample_rate_Hz, quantisation_m : float
        Sliding level at speed, force noise standard deviation, sampling, encoder step.
    """

    case: str
    seed: int
    time_s: np.ndarray
    position_m: np.ndarray
    force_N: np.ndarray
    effects: tuple[Effect, ...]
    expected: str
    C_v: float
    transition_velocity_m_per_s: float
    n_elements: int
    sliding_force_N: float
    noise_N: float
    sample_rate_Hz: float
    quantisation_m: float


def _loguniform(rng: np.random.Generator, low: float, high: float) -> float:
    return float(np.exp(rng.uniform(np.log(low), np.log(high))))


def draw_effect(name: str, size: float, truth: Truth, rng: np.random.Generator) -> Effect:
    """Parameters of one effect whose force is about ``size`` times the sliding level."""
    level = truth.sliding_force_N
    # sized at the trace's top speed / acceleration (floors only for traces too short to move)
    top_speed = max(float(np.max(np.abs(truth.velocity_m_s))), 1e-3)
    top_accel = max(float(np.max(np.abs(truth.acceleration_m_s2))), 0.1)
    duration = float(truth.time_s[-1] - truth.time_s[0])
    sign = float(rng.choice([-1.0, 1.0]))
    p: dict[str, float]
    if name == "viscous":
        p = {"c_Ns_per_m": size * level / top_speed}
    elif name == "stribeck":
        p = {"ratio": 1.0 + 1.3 * size, "v_s_m_per_s": rng.uniform(2.0, 10.0) * 1e-3}
    elif name == "dwell_time":
        # sized at the trace's median standstill: the break-away after it is ``size`` above
        # the limits (a gamma drawn alone, 0.05-0.1, gave peaks of 1-11 % of the level)
        tau = _loguniform(rng, 0.05, 0.5)
        median = median_standstill(truth)
        p = {"gamma": size / np.log1p(median / tau), "tau_s": tau, "median_standstill_s": median}
    elif name == "position_ripple":
        wavelength = _loguniform(rng, 0.5e-3, 8e-3)
        p = {
            "amplitude_N": size * level,
            "wavelength_m": wavelength,
            "phase_rad": rng.uniform(-np.pi, np.pi),
        }
    elif name == "offset":
        p = {"offset_N": sign * size * level}
    elif name == "reversal_transient":
        p = {"amplitude_N": 1.2 * size * level, "length_m": _loguniform(rng, 30e-6, 300e-6)}
    elif name == "drift":
        p = {"kappa": sign * size, "tau_s": rng.uniform(0.15, 0.5) * duration}
    elif name == "inertia":
        p = {"mass_kg": size * level / top_accel}
    elif name == "sensor_lowpass":
        p = {"cutoff_Hz": _loguniform(rng, 5.0, 40.0), "order": float(rng.integers(2, 5))}
    elif name == "unknown_stroke_profile":
        x = truth.position_m
        centre = 0.5 * (x.max() + x.min())
        p = {"beta": 1.5 * size, "centre_m": centre, "half_stroke_m": 0.5 * (x.max() - x.min())}
    elif name == "unknown_bumps":
        chosen = rng.choice(_often_crossed(truth), size=int(rng.integers(2, 5)), replace=False)
        p = {"height": 1.5 * size, "width_m": rng.uniform(0.1e-3, 0.5e-3)}
        p |= {f"position_m_{i}": float(c) for i, c in enumerate(chosen)}
    elif name == "unknown_time_modulation":
        lowest = max(0.05, 4.0 / duration)  # at least four periods: no drift can follow it
        p = {
            "beta": size,
            "frequency_Hz": rng.uniform(lowest, max(0.3, 2.0 * lowest)),
            "phase_rad": rng.uniform(-np.pi, np.pi),
        }
    else:
        raise ValueError(f"unknown effect {name!r}")
    return name, p


def median_standstill(truth: Truth) -> float:
    """Median length (s) of the trace's standstills between two motions."""
    moving = truth.velocity_m_s != 0.0
    starts = np.flatnonzero(moving[1:] & ~moving[:-1]) + 1
    stops = np.flatnonzero(~moving[1:] & moving[:-1]) + 1
    dwells = [
        truth.time_s[a] - truth.time_s[stops[stops < a][-1]] for a in starts if (stops < a).any()
    ]
    return float(np.median(dwells)) if dwells else 0.1


def _often_crossed(truth: Truth) -> np.ndarray:
    """Positions crossed most often in sliding (>= 1 mm apart), so a bump there is seen
    many times, in both directions, in the training and the held-out parts of a trace."""
    x = truth.position_m[:: max(truth.position_m.size // 20_000, 1)]
    grid = np.linspace(x.min(), x.max(), 202)[1:-1]
    crossings = np.count_nonzero(np.diff(np.sign(x[:, None] - grid), axis=0), axis=0)
    picked: list[float] = []
    for k in np.argsort(crossings)[::-1]:
        if all(abs(grid[k] - c) >= 1e-3 for c in picked):
            picked.append(float(grid[k]))
        if len(picked) == 6:
            break
    return np.array(picked)


def _scale_main(effect: Effect, factor: float) -> Effect:
    name, p = effect
    key = MAIN_PARAMETER[name]
    scaled = dict(p)
    scaled[key] = float(1.0 + (p[key] - 1.0) * factor if key == "ratio" else p[key] * factor)
    return name, scaled


def _draw_truth(rng: np.random.Generator, samples: int) -> tuple[Truth, float, float]:
    rate = float(rng.integers(10, 51) * 100)
    position, velocity, acceleration = trajectory(rng, rate, samples)
    n_elements = int(rng.integers(3, 13))
    breakaway = np.sort(np.exp(rng.uniform(np.log(0.2e-6), np.log(30e-6), n_elements)))
    breakaway[0], breakaway[-1] = 0.2e-6 * rng.uniform(1, 2), 30e-6 * rng.uniform(0.5, 1)
    C_v = rng.uniform(1.0, 1.3)
    sliding = _loguniform(rng, 3.0, 40.0)
    stick_limits = rng.dirichlet(np.full(n_elements, 1.5)) * sliding / C_v
    truth = Truth(
        stiffness_N_per_m=stick_limits / breakaway,
        breakaway_m=breakaway,
        C_v=C_v,
        transition_velocity_m_per_s=rng.uniform(0.1e-3, 0.8e-3),
        sample_rate_Hz=rate,
        time_s=np.arange(samples) / rate,
        position_m=position,
        velocity_m_s=velocity,
        acceleration_m_s2=acceleration,
    )
    noise = rng.uniform(0.005, 0.03) * truth.sliding_force_N
    quantisation = _loguniform(rng, 1e-9, 50e-9)
    return truth, noise, quantisation


def _effects_for(
    case: str, truth: Truth, rng: np.random.Generator
) -> tuple[tuple[Effect, ...], str]:
    if case == "none":
        return (), "none"
    if case in CATALOGUE:
        return (draw_effect(case, rng.uniform(0.1, 0.3), truth, rng),), case
    if case in UNKNOWN:
        return (draw_effect(case, rng.uniform(0.15, 0.3), truth, rng),), "unknown"
    for big_name, small_name in PAIRS:
        if case == f"pair_{big_name}_{small_name}":
            big = draw_effect(big_name, PAIR_SIZES[big_name, small_name], truth, rng)
            small = draw_effect(small_name, 0.1, truth, rng)
            base = friction(truth, ())
            big_rms = np.sqrt(np.mean((friction(truth, (big,)) - base) ** 2))
            small_rms = np.sqrt(np.mean((friction(truth, (small,)) - base) ** 2))
            small = _scale_main(small, big_rms / (PAIR_SIZE_RATIO * small_rms))
            return (big, small), big_name
    raise ValueError(f"unknown case {case!r}")


def baseline(seed: int, samples: int | None = None) -> tuple[Truth, float, float, np.ndarray]:
    """The effect-free part of a seed: truth, noise level, encoder step and the noise samples.

    The baseline, motion and noise depend on the seed only (the effects on seed and case),
    so two cases of one seed differ by exactly their effects.
    """
    rng = np.random.default_rng(seed)
    length = int(rng.integers(100_000, 200_001)) if samples is None else int(samples)
    truth, noise, quantisation = _draw_truth(rng, length)
    return truth, noise, quantisation, rng.normal(0.0, noise, length)


def make_trace(
    case: str, seed: int, samples: int | None = None, noise_cutoff_Hz: float | None = None
) -> Generated:
    """Generate one measured-like trace with hidden ``case`` effects.

    Parameters
    ----------
    case : str
        One of ``CASES``.
    seed : int
        Seed of every random draw (trace, nominal, effect sizes): same seed, same trace.
    samples : int, optional
        Trace length; by default 100 000-200 000 samples drawn from the seed.
    noise_cutoff_Hz : float, optional
        The force noise low-passed at this cutoff (a sensor's or a drive's filter: 2nd-order
        Butterworth, zero phase), at the same standard deviation; white by default.

    Returns
    -------
    Generated
        The trace and its truth.
    """
    if case not in CASES:
        raise ValueError(f"unknown case {case!r}; choose from {', '.join(CASES)}")
    truth, noise, quantisation, noise_N = baseline(seed, samples)
    if noise_cutoff_Hz is not None:
        sos = signal.butter(2, noise_cutoff_Hz, fs=truth.sample_rate_Hz, output="sos")
        noise_N = signal.sosfiltfilt(sos, noise_N)
        noise_N *= noise / np.std(noise_N)
    effects, expected = _effects_for(case, truth, np.random.default_rng([seed, CASES.index(case)]))
    return _generated(case, seed, truth, noise, quantisation, noise_N, effects, expected)


def with_effect(seed: int, name: str, params: dict[str, float]) -> Generated:
    """The seed's effect-free trace (the same motion, baseline and noise as every case of
    that seed) with one catalogue effect of the given parameters (spec names, SI units;
    other keys are ignored): to check what a diagnosis says it would have revealed.

    Parameters
    ----------
    seed : int
        The trace's seed.
    name : str
        One of ``CATALOGUE``.
    params : dict of str to float
        The effect's parameters.

    Returns
    -------
    Generated
        The trace; ``case`` is ``name``, ``expected`` too.
    """
    if name not in CATALOGUE:
        raise ValueError(f"unknown effect {name!r}; choose from {', '.join(CATALOGUE)}")
    truth, noise, quantisation, noise_N = baseline(seed)
    effect: Effect = (name, {k: float(v) for k, v in params.items()})
    return _generated(name, seed, truth, noise, quantisation, noise_N, (effect,), name)


def _generated(
    case: str, seed: int, truth: Truth, noise: float, quantisation: float,
    noise_N: np.ndarray, effects: tuple[Effect, ...], expected: str,
) -> Generated:  # fmt: skip
    force = friction(truth, effects) + noise_N
    return Generated(
        case=case,
        seed=seed,
        time_s=truth.time_s,
        position_m=np.round(truth.position_m / quantisation) * quantisation,
        force_N=force,
        effects=effects,
        expected=expected,
        C_v=truth.C_v,
        transition_velocity_m_per_s=truth.transition_velocity_m_per_s,
        n_elements=truth.breakaway_m.size,
        sliding_force_N=truth.sliding_force_N,
        noise_N=noise,
        sample_rate_Hz=truth.sample_rate_Hz,
        quantisation_m=quantisation,
    )


def write_csv(gen: Generated, path: str | os.PathLike[str]) -> Path:
    """Write the canonical CSV (time_s, position_m, force_N); return the path.

    Written beside the target and renamed, so a killed run leaves no partial file (the
    project's atomic writer is not used: this module imports nothing from the project).
    """
    target = Path(path)
    partial = target.with_name(f".{target.name}.{os.getpid()}.partial")
    table = np.column_stack([gen.time_s, gen.position_m, gen.force_N])
    np.savetxt(
        partial,
        table,
        fmt=("%.10g", "%.12g", "%.9g"),
        delimiter=",",
        header="time_s,position_m,force_N",
        comments="",
    )
    os.replace(partial, target)
    return target


def dwell_gain(params: dict[str, float], dwell_s: float) -> float:
    """The break-away gain less 1 after a standstill of ``dwell_s``: gamma ln(1 + t/tau)."""
    return float(params["gamma"]) * float(np.log1p(dwell_s / float(params["tau_s"])))


def parameter_error(effect: str, truth: dict[str, float], fitted: dict[str, float]) -> float:
    """Relative error of the effect's main parameter (of ratio - 1 for ``stribeck``,
    of the magnitude for ``position_ripple``'s amplitude, whose sign trades with its phase).

    For ``dwell_time``, of the gain after the trace's median standstill (what the effect is
    sized by), not of gamma: over dwells of 0.05-3 s, (gamma, tau) pairs that give the
    same gains at the trace's dwells cannot be told apart (a diagnosis's whole-trace RMS
    was within 3e-5 (relative) from tau 0.15 to 0.42 s on one trace, and gamma on that
    ridge followed tau), so gamma alone is not determined by the trace."""
    if effect == "dwell_time":
        dwell = truth["median_standstill_s"]
        want, got = dwell_gain(truth, dwell), dwell_gain(fitted, dwell)
        return abs(got - want) / abs(want)
    key = MAIN_PARAMETER[effect]
    want, got = truth[key], float(fitted[key])
    if key == "ratio":
        want, got = want - 1.0, got - 1.0
    if effect == "position_ripple":
        want, got = abs(want), abs(got)
    return abs(got - want) / abs(want)
