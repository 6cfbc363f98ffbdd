"""Trajectory families of the independent trace generator (see ``indepgen``).

Written from the specs only (the seed's step-and-stop profile, physics.md), sharing no code
with the project's own generator or with the diagnosis. Every family is built as a sampled
velocity profile that starts and ends at rest; position is its trapezoidal integral, so the
acceleration (for the drive-force ``inertia`` effect) is the derivative of a smooth velocity.
"""

from __future__ import annotations

import numpy as np

MM = 1e-3
UM = 1e-6


def _loguniform(rng: np.random.Generator, low: float, high: float) -> float:
    return float(np.exp(rng.uniform(np.log(low), np.log(high))))


def s_curve_move(distance_m: float, speed_m_s: float, ramp_s: float, rate_Hz: float) -> np.ndarray:
    """Velocity samples of a point-to-point move with raised-cosine acceleration ramps.

    Parameters
    ----------
    distance_m : float
        Signed travel.
    speed_m_s : float
        Cruise speed (reduced when the move is too short to reach it).
    ramp_s : float
        Duration of each acceleration ramp.
    rate_Hz : float
        Sample rate.

    Returns
    -------
    numpy.ndarray
        Velocity in m/s, starting and ending at zero; its integral is ``distance_m`` up to
        the sampling of the ramps.
    """
    length = abs(distance_m)
    speed = min(speed_m_s, length / ramp_s)
    cruise_s = length / speed - ramp_s
    n_ramp = max(round(ramp_s * rate_Hz), 2)
    n_cruise = max(round(cruise_s * rate_Hz), 0)
    ramp = 0.5 * (1.0 - np.cos(np.pi * np.arange(1, n_ramp + 1) / n_ramp))
    profile = np.concatenate([ramp, np.ones(n_cruise), ramp[::-1][1:], [0.0]])
    # scale so the trapezoidal integral is exactly the requested travel
    travel = np.sum(profile) / rate_Hz
    return np.sign(distance_m) * profile * (length / travel)


def _rest(seconds: float, rate_Hz: float) -> np.ndarray:
    return np.zeros(max(round(seconds * rate_Hz), 1))


def _toward_centre(position_m: float, rng: np.random.Generator) -> float:
    if abs(position_m) < 1 * MM:
        return float(rng.choice([-1.0, 1.0]))
    return -float(np.sign(position_m))


def step_and_stop(position_m: float, rng: np.random.Generator, rate_Hz: float) -> np.ndarray:
    """The seed's profile: small steps with a stop after each, out and back."""
    n_steps = int(rng.integers(3, 7))
    step_m = rng.uniform(0.05, 0.2) * MM * _toward_centre(position_m, rng)
    speed = rng.uniform(2.0, 20.0) * MM
    ramp_s = rng.uniform(0.003, 0.01)
    pieces: list[np.ndarray] = []
    for direction in (1.0, -1.0):
        for _ in range(n_steps):
            pieces.append(s_curve_move(direction * step_m, speed, ramp_s, rate_Hz))
            pieces.append(_rest(_loguniform(rng, 0.05, 3.0), rate_Hz))
    return np.concatenate(pieces)


def point_to_point(
    position_m: float, half_stroke_m: float, rng: np.random.Generator, rate_Hz: float
) -> np.ndarray:
    """S-curve moves between random targets, speeds spread over 1-100 mm/s."""
    pieces: list[np.ndarray] = []
    where = position_m
    bands = rng.permutation([(1.0, 5.0), (5.0, 25.0), (25.0, 100.0)])
    for move in range(int(rng.integers(3, 6))):
        target = rng.uniform(-half_stroke_m, half_stroke_m)
        if abs(target - where) < 1 * MM:
            target = where + 2 * MM * _toward_centre(where, rng)
        speed = _loguniform(rng, *bands[move % 3]) * MM  # slow, medium and fast in each block
        ramp_s = rng.uniform(0.02, 0.2)
        pieces.append(s_curve_move(target - where, speed, ramp_s, rate_Hz))
        pieces.append(_rest(_loguniform(rng, 0.05, 3.0), rate_Hz))
        where = target
    return np.concatenate(pieces)


def _cosine_cycles(
    amplitude_m: float, frequency_Hz: float, cycles: int, rate_Hz: float
) -> np.ndarray:
    # x = A (1 - cos wt): starts and ends at rest, reverses every half period
    t = np.arange(round(cycles * rate_Hz / frequency_Hz) + 1) / rate_Hz
    omega = 2 * np.pi * frequency_Hz
    velocity = amplitude_m * omega * np.sin(omega * t)
    # the last sample lands up to half a sample past the last cycle, where sin has turned:
    # a "reversal" of ~1e-11 m, far below any encoder step, that is no physical reversal
    # (it gave a full reversal transient through the rest that follows). End at rest.
    velocity[-1] = 0.0
    return velocity


def sines(position_m: float, rng: np.random.Generator, rate_Hz: float) -> np.ndarray:
    """One or two sines of different amplitudes (0.05-5 mm) and peak speeds (1-100 mm/s)."""
    pieces: list[np.ndarray] = []
    for _ in range(int(rng.integers(1, 3))):
        amplitude = _loguniform(rng, 0.05, 5.0) * MM
        peak_speed = _loguniform(rng, 1.0, 100.0) * MM
        frequency = float(np.clip(peak_speed / (2 * np.pi * amplitude), 0.1, 5.0))
        direction = _toward_centre(position_m, rng)
        pieces.append(
            direction * _cosine_cycles(amplitude, frequency, int(rng.integers(2, 5)), rate_Hz)
        )
        pieces.append(_rest(_loguniform(rng, 0.05, 1.0), rate_Hz))
    return np.concatenate(pieces)


def presliding(rng: np.random.Generator, rate_Hz: float) -> np.ndarray:
    """Micrometre reversals (1-20 um) that stay mostly inside the presliding range."""
    pieces: list[np.ndarray] = []
    for _ in range(int(rng.integers(1, 3))):
        amplitude = _loguniform(rng, 1.0, 20.0) * UM
        frequency = rng.uniform(0.5, 3.0)
        sign = float(rng.choice([-1.0, 1.0]))
        pieces.append(sign * _cosine_cycles(amplitude, frequency, int(rng.integers(3, 7)), rate_Hz))
        pieces.append(_rest(rng.uniform(0.2, 1.0), rate_Hz))
    return np.concatenate(pieces)


def trajectory(
    rng: np.random.Generator, rate_Hz: float, samples: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A mixed trajectory of exactly ``samples`` samples: position, velocity, acceleration.

    The families are cycled in a shuffled order (every cycle holds each family once) until
    the trace is long enough, so both directions, several speeds, reversals and standstills
    of 0.05-3 s occur all along the trace.
    """
    half_stroke = rng.uniform(10.0, 40.0) * MM
    pieces: list[np.ndarray] = [_rest(rng.uniform(0.1, 0.3), rate_Hz)]
    position = 0.0
    total = pieces[0].size
    while total < samples:
        for family in rng.permutation(4):
            if family == 0:
                piece = step_and_stop(position, rng, rate_Hz)
            elif family == 1:
                piece = point_to_point(position, half_stroke, rng, rate_Hz)
            elif family == 2:
                piece = sines(position, rng, rate_Hz)
            else:
                piece = presliding(rng, rate_Hz)
            pieces.append(piece)
            total += piece.size
            position += float(np.trapezoid(piece) / rate_Hz) if piece.size > 1 else 0.0
    velocity = np.concatenate(pieces)[:samples]
    dt = 1.0 / rate_Hz
    position_m = np.concatenate([[0.0], np.cumsum(0.5 * (velocity[1:] + velocity[:-1]) * dt)])
    acceleration = np.gradient(velocity, dt)
    return position_m, velocity, acceleration
