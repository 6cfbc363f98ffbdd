"""Cascade controller of the axis: P position loop around a PI velocity loop.

Designed in continuous time from the plant's mass and force constant and
discretized with python-control at the servo rate:

- velocity PI ``C_v(s) = K_v (s + w_i) / s`` with ``K_v = m w_v / k_f`` (A per m/s),
  so that the velocity loop crosses over near ``w_v``;
- position P ``K_p = w_p`` (1/s) on the position error, plus the reference
  velocity as feedforward into the velocity loop;
- the reference acceleration as current feedforward ``m a / k_f``, taken a few
  cycles ahead (``acceleration_lead_cycles``) to make up for the hold and the
  current loop;
- the velocity measured by differencing the encoder, through a first-order
  low-pass. The velocity feedforward is the reference position through the
  same estimator, so that under acceleration both lag alike and the velocity
  loop sees no error the estimator made up.

The PI and the filter become discrete state-space blocks (``control.c2d``); the
PI integrator stops integrating while the current command saturates in the
direction of the error (conditional anti-windup).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import control
import numba
import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.config import in_range, positive
from sim.plant import PlantConfig

# Layout of the compiled controller's gain vector ...
_KP, _PA, _PB, _PC, _PD, _FA, _FB, _FC, _FD, _ACC, _PERIOD, _LIMIT = range(12)
# ... and of its state: PI integrator, then the measured and the reference
# velocity estimators (filter state, last position, velocity each).
_PI, _MEASURED, _REFERENCE = 0, 1, 4
MEASURED_VELOCITY = _MEASURED + 2  # where the measured velocity estimate sits


@dataclass(frozen=True)
class ControllerConfig:
    """The ``[controller]`` section."""

    servo_rate_Hz: float = field(default=4000.0, metadata=in_range(100.0, 1e5))
    position_bandwidth_Hz: float = field(default=30.0, metadata=positive(5e4))
    velocity_bandwidth_Hz: float = field(default=150.0, metadata=positive(5e4))
    integral_corner_Hz: float = field(default=30.0, metadata=positive(5e4))
    velocity_filter_Hz: float = field(default=1000.0, metadata=positive(5e4))
    discretization: Literal["tustin", "zoh", "foh", "backward_diff"] = "tustin"
    acceleration_feedforward: bool = True
    acceleration_lead_cycles: int = field(default=1, metadata=in_range(0, 100))
    # structure = "position_velocity": the drive-command loop of sim.position_loop (the
    # EMPS benchmark's; defaults are its gains): u = kv (kp (qg - q) - d/dt FIR(q)),
    # delayed, saturated, times the drive gain.
    structure: Literal["cascade", "position_velocity"] = "cascade"
    kp_per_s: float = field(default=160.18, metadata=positive(1e5))
    kv_command_s_per_m: float = field(default=243.45, metadata=positive(1e7))
    drive_gain_N_per_command: float = field(default=35.15065188248547, metadata=positive(1e6))
    command_limit: float = field(default=10.0, metadata=positive(1e6))
    command_delay_cycles: int = field(default=1, metadata=in_range(0, 100))
    velocity_fir: tuple[float, ...] = field(
        default=(0.5, 0.5), metadata=in_range(-10.0, 10.0, max_items=8)
    )

    @property
    def servo_period_s(self) -> float:
        """One servo cycle."""
        return 1.0 / self.servo_rate_Hz

    def problems(self) -> list[tuple[str, str]]:
        """`velocity_bandwidth_Hz` and `velocity_filter_Hz` below half `servo_rate_Hz`;
        `position_bandwidth_Hz` and `integral_corner_Hz` below `velocity_bandwidth_Hz`;
        `velocity_fir` 1 to 8 taps summing to 1."""
        found = []
        nyquist = self.servo_rate_Hz / 2
        for name in ("velocity_bandwidth_Hz", "velocity_filter_Hz"):
            if getattr(self, name) >= nyquist:
                found.append((name, f"must be below half the servo rate ({nyquist:g} Hz)"))
        if self.position_bandwidth_Hz >= self.velocity_bandwidth_Hz:
            found.append(("position_bandwidth_Hz", "must be below velocity_bandwidth_Hz"))
        if self.integral_corner_Hz >= self.velocity_bandwidth_Hz:
            found.append(("integral_corner_Hz", "must be below velocity_bandwidth_Hz"))
        if not 1 <= len(self.velocity_fir) <= 8 or abs(sum(self.velocity_fir) - 1.0) > 1e-9:
            found.append(("velocity_fir", "must be 1 to 8 taps that sum to 1"))
        return found


@dataclass(frozen=True)
class DiscreteBlock:
    """A first-order discrete block ``x+ = a x + b e``, ``y = c x + d e``."""

    a: float
    b: float
    c: float
    d: float

    @classmethod
    def from_continuous(
        cls, sys: control.TransferFunction, period_s: float, method: str
    ) -> DiscreteBlock:
        """Discretize a first-order SISO transfer function."""
        d = control.ss(control.c2d(sys, period_s, method))
        a, b, c, dd = (float(np.asarray(m).item()) for m in (d.A, d.B, d.C, d.D))
        return cls(a, b, c, dd)


@dataclass(frozen=True)
class CascadeGains:
    """The designed controller."""

    position_gain_per_s: float
    velocity_pi: DiscreteBlock
    velocity_filter: DiscreteBlock
    acceleration_gain_A_s2_per_m: float
    servo_period_s: float


def design(plant: PlantConfig, cfg: ControllerConfig) -> CascadeGains:
    """Design and discretize the cascade for ``plant``."""
    wv = 2 * math.pi * cfg.velocity_bandwidth_Hz
    wi = 2 * math.pi * cfg.integral_corner_Hz
    wf = 2 * math.pi * cfg.velocity_filter_Hz
    kv = plant.moving_mass_kg * wv / plant.force_constant_N_per_A
    pi = control.tf([kv, kv * wi], [1.0, 0.0])
    lowpass = control.tf([wf], [1.0, wf])
    ts = cfg.servo_period_s
    ff = plant.moving_mass_kg / plant.force_constant_N_per_A if cfg.acceleration_feedforward else 0
    return CascadeGains(
        position_gain_per_s=2 * math.pi * cfg.position_bandwidth_Hz,
        velocity_pi=DiscreteBlock.from_continuous(pi, ts, cfg.discretization),
        velocity_filter=DiscreteBlock.from_continuous(lowpass, ts, cfg.discretization),
        acceleration_gain_A_s2_per_m=ff,
        servo_period_s=ts,
    )


@numba.njit(cache=True)
def _estimate(
    gains: FloatArray, state: FloatArray, at: int, position_m: float
) -> float:  # pragma: no cover
    """Velocity estimator in ``state[at:at + 3] = [filter state, last position, velocity]``:
    backward difference through the discrete low-pass."""
    raw = (position_m - state[at + 1]) / gains[_PERIOD]
    state[at + 1] = position_m
    velocity = gains[_FC] * state[at] + gains[_FD] * raw
    state[at] = gains[_FA] * state[at] + gains[_FB] * raw
    state[at + 2] = velocity
    return velocity


@numba.njit(cache=True)
def controller_step(
    gains: FloatArray,
    state: FloatArray,
    measured_position_m: float,
    reference_position_m: float,
    reference_acceleration_m_s2: float,
    feedforward_current_A: float,
) -> float:  # pragma: no cover
    """One cycle of the cascade (:class:`CascadeController`); the clipped current command."""
    velocity_command = gains[_KP] * (reference_position_m - measured_position_m) + _estimate(
        gains, state, _REFERENCE, reference_position_m
    )
    error = velocity_command - _estimate(gains, state, _MEASURED, measured_position_m)
    command = (
        gains[_PC] * state[_PI]
        + gains[_PD] * error
        + gains[_ACC] * reference_acceleration_m_s2
        + feedforward_current_A
    )
    limit = gains[_LIMIT]
    clipped = min(max(command, -limit), limit)
    if clipped == command or (command > clipped) != (error > 0):
        state[_PI] = gains[_PA] * state[_PI] + gains[_PB] * error
    return clipped


class CascadeController:
    """The discrete cascade, one servo cycle per :meth:`step` (:func:`controller_step`).

    ``gains`` and ``state`` are the arrays the compiled step works on.
    """

    def __init__(
        self, gains: CascadeGains, current_limit_A: float, acceleration_lead_cycles: int = 0
    ) -> None:
        self.design = gains
        self.acceleration_lead_cycles = acceleration_lead_cycles
        self.current_limit_A = current_limit_A
        pi, f = gains.velocity_pi, gains.velocity_filter
        self.gains = np.array(
            [
                gains.position_gain_per_s,
                pi.a, pi.b, pi.c, pi.d,
                f.a, f.b, f.c, f.d,
                gains.acceleration_gain_A_s2_per_m,
                gains.servo_period_s,
                current_limit_A,
            ]
        )  # fmt: skip
        self.state = np.zeros(7)
        self.reset()

    @property
    def velocity_m_s(self) -> float:
        """The estimated velocity of the axis."""
        return float(self.state[_MEASURED + 2])

    def reset(self, position_m: float = 0.0) -> None:
        """At rest at ``position_m``."""
        self.state[:] = 0.0
        self.state[_MEASURED + 1] = position_m
        self.state[_REFERENCE + 1] = position_m

    def step(
        self,
        measured_position_m: float,
        reference_position_m: float,
        reference_acceleration_m_s2: float,
        feedforward_current_A: float,
    ) -> float:
        """Return the current command for this cycle (clipped to the current limit)."""
        return float(
            controller_step(
                self.gains,
                self.state,
                measured_position_m,
                reference_position_m,
                reference_acceleration_m_s2,
                feedforward_current_A,
            )
        )
