"""The friction truth of the independent trace generator (see ``indepgen``).

A plain Maxwell-slip model (its own play operator) whose element limits follow the seed's
slip level above stick, and the catalogue's effect forms (``measured-data.md``) plus the
generator's uncatalogued ones, written from the specs only: numpy/scipy, no project code.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

Effect = tuple[str, dict[str, float]]


@dataclass(frozen=True, eq=False)
class Truth:
    """The baseline friction and the motion it is evaluated on (SI units)."""

    stiffness_N_per_m: np.ndarray
    breakaway_m: np.ndarray
    C_v: float
    transition_velocity_m_per_s: float
    sample_rate_Hz: float
    time_s: np.ndarray
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    acceleration_m_s2: np.ndarray

    @property
    def sliding_force_N(self) -> float:
        """Steady sliding force well above the transition velocity."""
        return float(self.C_v * np.sum(self.stiffness_N_per_m * self.breakaway_m))


def play_operator(
    displacement_m: np.ndarray,
    stiffness_N_per_m: np.ndarray,
    breakaway_m: np.ndarray,
    level: np.ndarray,
    boost_at: np.ndarray | None = None,
) -> np.ndarray:
    """Maxwell-slip friction: each element is a spring clipped at its break-away limit.

    Parameters
    ----------
    displacement_m : numpy.ndarray
        Position increment into each sample (the first entry is the step into sample 0).
    stiffness_N_per_m, breakaway_m : numpy.ndarray
        Element stiffnesses and break-away displacements (limit = k * breakaway).
    level : numpy.ndarray
        Per-sample factor on every element's limit (velocity level, other level effects).
    boost_at : numpy.ndarray, optional
        Per-sample break-away gain set on all elements at that sample (values > 1 after a
        standstill); an element keeps its gain until it slips, then loses it.

    Returns
    -------
    numpy.ndarray
        Friction force per sample, positive when pushing towards +x.
    """
    limit0 = breakaway_m.astype(float)
    spring = np.zeros_like(limit0)
    gain = np.ones_like(limit0)
    force = np.empty(displacement_m.size)
    boosts = np.ones(displacement_m.size) if boost_at is None else boost_at
    for k in range(displacement_m.size):
        if k and displacement_m[k] == 0.0 and level[k] == level[k - 1] and boosts[k] == 1.0:
            force[k] = force[k - 1]  # at rest under a constant limit nothing can change
            continue
        if boosts[k] != 1.0:
            gain[:] = boosts[k]
        limit = limit0 * level[k]
        moved = spring + displacement_m[k]
        slipped = np.abs(moved) > limit * gain
        if slipped.any():
            gain[slipped] = 1.0
            moved[slipped] = np.sign(moved[slipped]) * limit[slipped]
        spring = moved
        force[k] = float(stiffness_N_per_m @ spring)
    return force


def velocity_level(speed_m_s: np.ndarray, C_v: float, transition_m_s: float) -> np.ndarray:
    """The baseline's limit factor: 1 at rest, C_v in sliding, reached smoothly."""
    q = (speed_m_s / transition_m_s) ** 2
    return 1.0 + (C_v - 1.0) * q / (1.0 + q)


def _standstill_gain(truth: Truth, gamma: float, tau_s: float) -> np.ndarray:
    """Break-away gain 1 + gamma ln(1 + t_d / tau) at each first sample after a standstill."""
    moving = truth.velocity_m_s != 0.0
    gain = np.ones(moving.size)
    starts = np.flatnonzero(moving[1:] & ~moving[:-1]) + 1
    stops = np.flatnonzero(~moving[1:] & moving[:-1]) + 1
    for start in starts:
        before = stops[stops < start]
        if before.size:
            dwell = truth.time_s[start] - truth.time_s[before[-1]]
            gain[start] = 1.0 + gamma * np.log1p(dwell / tau_s)
    return gain


def _reversal_decay(truth: Truth, length_m: float) -> np.ndarray:
    """d exp(-s / l): direction held through standstills, s travelled since the last reversal."""
    step = np.diff(truth.position_m, prepend=truth.position_m[0])
    direction = np.sign(truth.velocity_m_s)
    for k in range(1, direction.size):
        if direction[k] == 0.0:
            direction[k] = direction[k - 1]
    out = np.zeros(direction.size)
    travelled = np.inf
    for k in range(1, direction.size):
        if direction[k] != direction[k - 1] and direction[k - 1] != 0.0:
            travelled = 0.0
        travelled += abs(step[k])
        out[k] = direction[k] * np.exp(-travelled / length_m)
    return out


def friction(truth: Truth, effects: tuple[Effect, ...]) -> np.ndarray:
    """The true force (before sensor noise) of the baseline with ``effects`` added."""
    named = dict(effects)
    speed = np.abs(truth.velocity_m_s)
    level = velocity_level(speed, truth.C_v, truth.transition_velocity_m_per_s)
    if "stribeck" in named:
        p = named["stribeck"]
        level = level * (1.0 + (p["ratio"] - 1.0) * np.exp(-((speed / p["v_s_m_per_s"]) ** 2)))
    level = level * _unknown_level(truth, named)
    boost = None
    if "dwell_time" in named:
        boost = _standstill_gain(truth, named["dwell_time"]["gamma"], named["dwell_time"]["tau_s"])
    step = np.diff(truth.position_m, prepend=truth.position_m[0])
    force = play_operator(step, truth.stiffness_N_per_m, truth.breakaway_m, level, boost)
    if "drift" in named:
        p = named["drift"]
        force = force * (1.0 + p["kappa"] * -np.expm1(-truth.time_s / p["tau_s"]))
    force = force + _additive(truth, named)
    if "sensor_lowpass" in named:
        p = named["sensor_lowpass"]
        sos = signal.butter(int(p["order"]), p["cutoff_Hz"], fs=truth.sample_rate_Hz, output="sos")
        force = signal.sosfilt(sos, force)
    return force


def _additive(truth: Truth, named: dict[str, dict[str, float]]) -> np.ndarray:
    x = truth.position_m
    out = np.zeros(x.size)
    if "viscous" in named:
        out += named["viscous"]["c_Ns_per_m"] * truth.velocity_m_s
    if "position_ripple" in named:
        p = named["position_ripple"]
        out += p["amplitude_N"] * np.sin(2 * np.pi * x / p["wavelength_m"] + p["phase_rad"])
    if "offset" in named:
        out += named["offset"]["offset_N"]
    if "reversal_transient" in named:
        p = named["reversal_transient"]
        out += p["amplitude_N"] * _reversal_decay(truth, p["length_m"])
    if "inertia" in named:
        out += named["inertia"]["mass_kg"] * truth.acceleration_m_s2
    return out


def _unknown_level(truth: Truth, named: dict[str, dict[str, float]]) -> np.ndarray:
    x = truth.position_m
    level = np.ones(x.size)
    if "unknown_stroke_profile" in named:
        p = named["unknown_stroke_profile"]
        level *= 1.0 + p["beta"] * ((x - p["centre_m"]) / p["half_stroke_m"]) ** 2
    if "unknown_bumps" in named:
        p = named["unknown_bumps"]
        bumps = [v for k, v in p.items() if k.startswith("position_m_")]
        level *= 1.0 + p["height"] * sum(np.exp(-(((x - c) / p["width_m"]) ** 2)) for c in bumps)
    if "unknown_time_modulation" in named:
        p = named["unknown_time_modulation"]
        level *= 1.0 + p["beta"] * np.sin(
            2 * np.pi * p["frequency_Hz"] * truth.time_s + p["phase_rad"]
        )
    return level
