"""The simulated linear-motor axis: moving mass, current loop, encoder, friction truth.

The linear part follows python-control's convention: :func:`dynamics` is
``f(t, x, u, params)`` with state ``x = [position_m, velocity_m_s, current_A]``
(plus ``current_rate_A_s`` for a second-order current loop) and input
``u = [current_command_A, external_force_N]``. :func:`linear_system` builds the
same model as a :class:`control.StateSpace`; :class:`LinearMotorAxis` advances it
by exact zero-order-hold steps (the compiled :func:`axis_cycle`, shared by the
closed loop's kernel) and closes it over a friction model, which is
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
from typing import Any, Literal

import control
import numba
import numpy as np
from numpy.typing import NDArray

from gms_comp.arrays import FloatArray
from gms_comp.config import in_range, non_negative, positive
from gms_comp.errors import ScenarioError
from gms_comp.runtime.observer import ForceModel
from gms_comp.validation import MAX_SEED
from sim.kernels import Pack, truth_force, truth_pack, zero_truth


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

    source: ForceModel
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

    moving_mass_kg: float = field(default=30.0, metadata=in_range(1e-3, 1e4))
    force_constant_N_per_A: float = field(default=60.0, metadata=in_range(1e-2, 1e4))
    current_limit_A: float = field(default=10.0, metadata=in_range(1e-3, 1e3))
    current_loop_bandwidth_Hz: float = field(default=1500.0, metadata=positive(1e5))
    current_loop_order: Literal[1, 2] = 1
    current_loop_damping: float = field(default=0.7, metadata=in_range(0.05, 5.0))
    encoder_resolution_m: float = field(default=1e-9, metadata=non_negative(1e-3))
    position_noise_m: float = field(default=1e-9, metadata=non_negative(1e-3))
    noise_seed: int = field(default=0, metadata=in_range(0, MAX_SEED))
    ball_set_count: float = field(default=40.0, metadata=non_negative(1e4))
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


def compiled_truth(friction: ForceModel, scale: float = 1.0) -> Pack:
    """The :mod:`sim.kernels` pack of a friction truth (after its reset).

    Raises
    ------
    ScenarioError
        If the truth has no compiled form (the transient ball set, GMS, none,
        or those scaled by :class:`ScaledFriction`).
    """
    if isinstance(friction, ScaledFriction):
        return compiled_truth(friction.source, scale * friction.count)
    if isinstance(friction, ZeroFriction):
        return zero_truth()
    pack = truth_pack(friction, scale)
    if pack is None:
        raise ScenarioError(
            f"friction truth {type(friction).__name__} has no compiled form "
            "(use the ball set, a GMS model or none)"
        )
    return pack


@numba.njit(cache=True)
def axis_cycle(
    x: FloatArray,
    ad: FloatArray,
    bd: FloatArray,
    params: FloatArray,
    io: FloatArray,
    noise: FloatArray,
    truth: Pack,
    current_command_A: float,
) -> float:  # pragma: no cover
    """Advance the axis one servo cycle; return the encoder reading at its end.

    ``x`` is the padded state (4), ``ad``/``bd`` the ZOH matrices of one sub-step,
    ``params = [current limit, sub-steps, noise rms, encoder resolution]``,
    ``io = [next noise index, last friction force, extra resisting force]``. The friction
    is evaluated at the start of each sub-step and held over it; the extra force (a
    simulated machine's hidden effect, 0 otherwise) is held over the cycle.
    """
    limit = params[0]
    u = min(max(current_command_A, -limit), limit)
    f = 0.0
    for _ in range(int(params[1])):
        f = -truth_force(truth, x[0], x[1]) - io[2]
        x0, x1, x2, x3 = x[0], x[1], x[2], x[3]
        for i in range(4):
            x[i] = (
                ad[i, 0] * x0
                + ad[i, 1] * x1
                + ad[i, 2] * x2
                + ad[i, 3] * x3
                + bd[i, 0] * u
                + bd[i, 1] * f
            )
    io[1] = -f
    return encoder(x, params, io, noise)


@numba.njit(cache=True)
def encoder(
    x: FloatArray, params: FloatArray, io: FloatArray, noise: FloatArray
) -> float:  # pragma: no cover
    """Encoder reading: true position plus the next noise sample, quantized."""
    reading = x[0]
    if params[2] > 0.0:
        k = int(io[0])
        reading += params[2] * noise[k % noise.size]
        io[0] = k + 1
    if params[3] > 0.0:
        reading = round(reading / params[3]) * params[3]
    return reading


class LinearMotorAxis:
    """The axis advanced one servo cycle at a time, with its friction truth.

    Parameters
    ----------
    cfg
        Plant parameters.
    friction
        The friction truth (resisting force, see module docstring); one with a
        compiled form (:func:`compiled_truth`).
    servo_period_s
        Length of one servo cycle; the current command is held over it.

    Examples
    --------
    >>> axis = LinearMotorAxis(PlantConfig(encoder_resolution_m=0.0,
    ...     position_noise_m=0.0), ZeroFriction(), 2.5e-4)
    >>> axis.step(1.0) > 0.0
    True
    """

    def __init__(self, cfg: PlantConfig, friction: ForceModel, servo_period_s: float) -> None:
        self.cfg = cfg
        self.friction = friction
        discrete = control.c2d(linear_system(cfg), servo_period_s / cfg.substeps, "zoh")
        # Padded to four states (a first-order current loop leaves the last at 0).
        n = state_size(cfg)
        self.ad = np.zeros((4, 4))
        self.bd = np.zeros((4, 2))
        self.ad[:n, :n] = discrete.A
        self.bd[:n] = discrete.B
        self.params = np.array(
            [cfg.current_limit_A, cfg.substeps, cfg.position_noise_m, cfg.encoder_resolution_m]
        )
        self.state = np.zeros(4)
        self.io = np.zeros(3)
        self.reset()

    def reset(self, cycles: int = 4096) -> None:
        """At rest at 0 m, no current, friction virgin, no extra force, noise re-seeded for
        ``cycles`` readings (then repeated)."""
        self.state[:] = 0.0
        self.io[:] = 0.0
        self.friction.reset()
        self.truth = compiled_truth(self.friction)
        self.noise = np.random.default_rng(self.cfg.noise_seed).standard_normal(max(1, cycles))

    @property
    def position_m(self) -> float:
        """True carriage position."""
        return float(self.state[0])

    @property
    def velocity_m_s(self) -> float:
        """True carriage velocity."""
        return float(self.state[1])

    @property
    def current_A(self) -> float:
        """Motor current."""
        return float(self.state[2])

    @property
    def friction_force_N(self) -> float:
        """Resisting friction force over the last sub-step (the extra force included)."""
        return float(self.io[1])

    def hold_extra_force(self, force_N: float) -> None:
        """A resisting force on top of the friction truth, held until changed."""
        self.io[2] = force_N

    def measure(self) -> float:
        """Encoder reading: true position plus noise, quantized to the resolution."""
        return float(encoder(self.state, self.params, self.io, self.noise))

    def compiled(self) -> tuple[Any, ...]:
        """The arguments of :func:`axis_cycle` before the command."""
        return (self.state, self.ad, self.bd, self.params, self.io, self.noise, self.truth)

    def step(self, current_command_A: float) -> float:
        """Hold ``current_command_A`` (clipped to the limit) over one cycle; return the
        encoder reading at its end."""
        x, ad, bd, params, io, noise, truth = self.compiled()
        return float(axis_cycle(x, ad, bd, params, io, noise, truth, current_command_A))
