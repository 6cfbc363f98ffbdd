"""The simulated linear-motor axis: moving mass, current loop, encoder, friction truth.

The linear part follows python-control's convention: :func:`dynamics` is
``f(t, x, u, params)`` with state ``x = [position_m, velocity_m_s, current_A]``
(plus ``current_rate_A_s`` for a second-order current loop) and input
``u = [current_command_A, external_force_N]``. :func:`linear_system` builds the
same model as a :class:`control.StateSpace`; :class:`LinearMotorAxis` advances it
by exact zero-order-hold steps and closes it over a friction model, which is
evaluated once per sub-step and held over it. The friction is displacement
driven (bristles, play operators), so holding it over a sub-step is stable.

Friction sign convention (the physics layer's): the friction model returns the
resisting force ``F`` with ``F * v >= 0`` in steady sliding; the axis feels
``-F``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, Protocol

import control
import numpy as np
from numpy.typing import NDArray

from gms_comp.config import in_range, non_negative, positive


class Friction(Protocol):
    """A streaming friction model: the resisting force on the carriage."""

    def reset(self) -> None:
        """Return to the virgin state (at rest, no bristle deflection)."""

    def step(self, position_m: float, velocity_m_s: float) -> float:
        """Advance to ``position_m`` and return the resisting force in N."""
        ...


class ZeroFriction:
    """No friction: the linear axis alone."""

    def reset(self) -> None:
        """Nothing to reset."""

    def step(self, position_m: float, velocity_m_s: float) -> float:
        """Always 0 N."""
        return 0.0


@dataclass(frozen=True)
class ScaledFriction:
    """``count`` identical friction sources moving together: the force is scaled.

    A guide carriage holds many ball rows loaded alike; identical contacts in
    parallel see the same displacement, so one model times their count is exact.
    """

    source: Friction
    count: float

    def reset(self) -> None:
        """Reset the underlying model."""
        self.source.reset()

    def step(self, position_m: float, velocity_m_s: float) -> float:
        """Force of the source times the count."""
        return self.count * self.source.step(position_m, velocity_m_s)


@dataclass(frozen=True)
class PlantConfig:
    """The ``[plant]`` section: a linear-motor axis of a precision machine.

    Defaults: a 30 kg carriage, a 60 N/A iron-core motor with a 10 A current
    limit, a 1.5 kHz current loop, a 1 nm linear encoder with 1 nm rms noise, and a
    guide with 40 copies of the configured ball set (160 balls for the seed's
    four-ball stand: four carriages, four ball rows each, ten loaded balls per row).
    """

    moving_mass_kg: float = field(default=30.0, metadata=positive())
    force_constant_N_per_A: float = field(default=60.0, metadata=positive())
    current_limit_A: float = field(default=10.0, metadata=positive())
    current_loop_bandwidth_Hz: float = field(default=1500.0, metadata=positive())
    current_loop_order: Literal[1, 2] = 1
    current_loop_damping: float = field(default=0.7, metadata=in_range(0.05, 5.0))
    encoder_resolution_m: float = field(default=1e-9, metadata=non_negative())
    position_noise_m: float = field(default=1e-9, metadata=non_negative())
    noise_seed: int = 0
    ball_set_count: float = field(default=40.0, metadata=non_negative())
    substeps: int = field(default=1, metadata=in_range(1, 64))


def state_size(cfg: PlantConfig) -> int:
    """Number of states: position, velocity, current (and current rate)."""
    return 2 + cfg.current_loop_order


def dynamics(
    t: float, x: NDArray[np.float64], u: NDArray[np.float64], params: Mapping[str, Any]
) -> NDArray[np.float64]:
    """State derivative of the axis (python-control's ``updfcn`` signature).

    ``params`` holds the :class:`PlantConfig` fields by name (:func:`plant_params`).
    ``u[0]`` is the current command, clipped to the current limit; ``u[1]`` an
    external force on the carriage (``-friction``).
    """
    limit_A = params["current_limit_A"]
    command_A = min(max(float(u[0]), -limit_A), limit_A)
    wc = 2 * math.pi * params["current_loop_bandwidth_Hz"]
    accel = (params["force_constant_N_per_A"] * x[2] + u[1]) / params["moving_mass_kg"]
    if params["current_loop_order"] == 1:
        return np.array([x[1], accel, wc * (command_A - x[2])])
    zeta = params["current_loop_damping"]
    current_accel = wc * wc * (command_A - x[2]) - 2 * zeta * wc * x[3]
    return np.array([x[1], accel, x[3], current_accel])


def plant_params(cfg: PlantConfig) -> dict[str, Any]:
    """The parameter dictionary :func:`dynamics` reads."""
    return dataclasses.asdict(cfg)


def linear_system(cfg: PlantConfig) -> control.StateSpace:
    """The unsaturated axis as a state-space model; inputs current command, force."""
    n = state_size(cfg)
    a = np.zeros((n, n))
    b = np.zeros((n, 2))
    wc = 2 * math.pi * cfg.current_loop_bandwidth_Hz
    a[0, 1] = 1.0
    a[1, 2] = cfg.force_constant_N_per_A / cfg.moving_mass_kg
    b[1, 1] = 1.0 / cfg.moving_mass_kg
    if cfg.current_loop_order == 1:
        a[2, 2] = -wc
        b[2, 0] = wc
    else:
        a[2, 3] = 1.0
        a[3, 2] = -wc * wc
        a[3, 3] = -2 * cfg.current_loop_damping * wc
        b[3, 0] = wc * wc
    c = np.zeros((1, n))
    c[0, 0] = 1.0
    return control.ss(a, b, c, np.zeros((1, 2)))


class LinearMotorAxis:
    """The axis advanced one servo cycle at a time, with its friction truth.

    Parameters
    ----------
    cfg
        Plant parameters.
    friction
        The friction truth (resisting force, see module docstring).
    servo_period_s
        Length of one servo cycle; the current command is held over it.

    Examples
    --------
    >>> axis = LinearMotorAxis(PlantConfig(encoder_resolution_m=0.0,
    ...     position_noise_m=0.0), ZeroFriction(), 2.5e-4)
    >>> axis.step(1.0) > 0.0
    True
    """

    def __init__(self, cfg: PlantConfig, friction: Friction, servo_period_s: float) -> None:
        self.cfg = cfg
        self.friction = friction
        discrete = control.c2d(linear_system(cfg), servo_period_s / cfg.substeps, "zoh")
        # Padded to four states (a first-order current loop leaves the last at 0) and
        # held as Python floats: the per-cycle update is then plain float arithmetic,
        # several times faster than numpy on arrays this small.
        n = state_size(cfg)
        ad = np.zeros((4, 4))
        bd = np.zeros((4, 2))
        ad[:n, :n] = discrete.A
        bd[:n] = discrete.B
        self._ad = tuple(tuple(map(float, row)) for row in ad)
        self._bd = tuple(tuple(map(float, row)) for row in bd)
        self._noise_block = 4096
        self.reset()

    def reset(self) -> None:
        """At rest at 0 m, no current, friction virgin, noise re-seeded."""
        self.state = [0.0] * 4
        self.friction.reset()
        self.friction_force_N = 0.0
        self._rng = np.random.default_rng(self.cfg.noise_seed)
        self._noise: list[float] = []

    @property
    def position_m(self) -> float:
        """True carriage position."""
        return self.state[0]

    @property
    def velocity_m_s(self) -> float:
        """True carriage velocity."""
        return self.state[1]

    @property
    def current_A(self) -> float:
        """Motor current."""
        return self.state[2]

    def measure(self) -> float:
        """Encoder reading: true position plus noise, quantized to the resolution."""
        cfg = self.cfg
        reading = self.state[0]
        if cfg.position_noise_m > 0:
            if not self._noise:
                self._noise = self._rng.standard_normal(self._noise_block).tolist()
            reading += cfg.position_noise_m * self._noise.pop()
        if cfg.encoder_resolution_m > 0:
            reading = round(reading / cfg.encoder_resolution_m) * cfg.encoder_resolution_m
        return reading

    def step(self, current_command_A: float) -> float:
        """Hold ``current_command_A`` (clipped to the limit) over one cycle; return the
        encoder reading at its end."""
        limit = self.cfg.current_limit_A
        u = min(max(current_command_A, -limit), limit)
        (a0, a1, a2, a3), (b0, b1, b2, b3) = self._ad, self._bd
        x0, x1, x2, x3 = self.state
        for _ in range(self.cfg.substeps):
            f = -self.friction.step(x0, x1)
            x0, x1, x2, x3 = (
                a0[0] * x0 + a0[1] * x1 + a0[2] * x2 + a0[3] * x3 + b0[0] * u + b0[1] * f,
                a1[0] * x0 + a1[1] * x1 + a1[2] * x2 + a1[3] * x3 + b1[0] * u + b1[1] * f,
                a2[0] * x0 + a2[1] * x1 + a2[2] * x2 + a2[3] * x3 + b2[0] * u + b2[1] * f,
                a3[0] * x0 + a3[1] * x1 + a3[2] * x2 + a3[3] * x3 + b3[0] * u + b3[1] * f,
            )
            self.friction_force_N = -f
        self.state = [x0, x1, x2, x3]
        return self.measure()
