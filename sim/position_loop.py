"""A drive-command position loop around a rigid axis: the EMPS benchmark's closed loop.

The loop (Janot, Gautier, Brunot 2019, the benchmark's Simulink model), per servo
cycle ``k`` of period ``T``::

    qf(k) = sum_i fir_i q(k - i)                      filtered position
    u(k)  = kv (kp (qg(k) - q(k)) - (qf(k) - qf(k-1)) / T) + ff(k)
    drive command = sat(u(k - delay), +-limit) + d(t)  disturbance after the saturation
    axis force    = drive_gain * drive command         (through a first-order lag)
    m ddq = axis force - friction(q, dq) - offset

The plant is integrated by RK4 with ``substeps`` steps per cycle. The friction of a
:class:`RigidAxisModel` has a memoryless part evaluated at every RK4 stage (Coulomb
``sign(v)`` per direction, viscous per direction, position ripple, offset, the
Stribeck factor on the GMS force) and a part with memory stepped once per sub-step and
held over it (the GMS elements, the transient after a reversal). With a pure
Coulomb+viscous model this is the benchmark's own integration (RK4, 10 sub-steps).

Everything runs in one compiled call (:func:`run_position_loop`); the feedforward is an
input array, so a compensator fed with the reference (whatever path carries it) is
computed before the run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from gms_comp import gms as gms_kernel
from gms_comp.arrays import FloatArray
from gms_comp.gms import GmsParams, GmsStream
from sim.controller import ControllerConfig
from sim.kernels import Pack, truth_force, zero_truth

MAX_FIR_TAPS = 8

# Layout of the loop's parameter vector ...
_T, _KP, _KV, _GAIN, _LIMIT, _DELAY, _SUBSTEPS, _NTAPS, _TAPS = range(9)
# ... and of the plant's.
(_MASS, _OFFSET, _FC_POS, _FC_NEG, _FV_POS, _FV_NEG, _STRIBECK_RATIO, _STRIBECK_V,
 _REV_AMP, _REV_LEN, _RIPPLE_AMP, _RIPPLE_WL, _RIPPLE_PHASE, _LAG, _HAS_GMS,
 _REV_DEADBAND, _N_PLANT) = range(17)  # fmt: skip

_NO_GMS = GmsStream(GmsParams(np.ones(1), np.zeros(1))).kernel


@dataclass(frozen=True)
class PositionLoop:
    """The loop's structure and gains (``[controller] structure = "position_velocity"``).

    ``velocity_gain_per_m_s`` is in command units per m/s, ``drive_gain_N`` in N per
    command unit (EMPS: volts, ``kv`` in V s/m, ``gtau`` in N/V).
    """

    period_s: float
    position_gain_per_s: float
    velocity_gain_per_m_s: float
    drive_gain_N: float
    command_limit: float
    delay_cycles: int = 1
    velocity_fir: tuple[float, ...] = (0.5, 0.5)
    substeps: int = 10

    @classmethod
    def from_config(cls, cfg: ControllerConfig, substeps: int = 10) -> PositionLoop:
        """The loop a ``[controller]`` section describes (its position-velocity keys)."""
        return cls(
            period_s=cfg.servo_period_s,
            position_gain_per_s=cfg.kp_per_s,
            velocity_gain_per_m_s=cfg.kv_command_s_per_m,
            drive_gain_N=cfg.drive_gain_N_per_command,
            command_limit=cfg.command_limit,
            delay_cycles=cfg.command_delay_cycles,
            velocity_fir=tuple(cfg.velocity_fir),
            substeps=substeps,
        )

    def params(self) -> FloatArray:
        """The compiled loop's parameter vector."""
        taps = np.zeros(MAX_FIR_TAPS)
        taps[: len(self.velocity_fir)] = self.velocity_fir
        head = [
            self.period_s,
            self.position_gain_per_s,
            self.velocity_gain_per_m_s,
            self.drive_gain_N,
            self.command_limit,
            self.delay_cycles,
            self.substeps,
            len(self.velocity_fir),
        ]
        return np.concatenate([head, taps])


@dataclass(frozen=True)
class RigidAxisModel:
    """A rigid moving mass and its friction (resisting force, ``F v >= 0`` sliding).

    ``friction = Fc(dir) sign(v) + Fv(dir) v + GMS(q) (1 + (ratio - 1) exp(-(v/v_s)^2))
    + A_rev dir exp(-s_rev / L_rev) + A_rip sin(2 pi q / lambda + phi) + offset``,
    with ``dir`` the direction of motion and ``s_rev`` the travel since the last
    reversal (a retreat of more than ``reversal_deadband_m``). ``drive_lag_s`` > 0 makes
    the axis force a first-order lag of the drive's command.
    """

    mass_kg: float
    offset_N: float = 0.0
    coulomb_pos_N: float = 0.0
    coulomb_neg_N: float = 0.0
    viscous_pos_Ns_per_m: float = 0.0
    viscous_neg_Ns_per_m: float = 0.0
    gms: GmsParams | None = None
    stribeck_ratio: float = 1.0
    stribeck_velocity_m_s: float = 1.0
    reversal_amplitude_N: float = 0.0
    reversal_length_m: float = 1.0
    ripple_amplitude_N: float = 0.0
    ripple_wavelength_m: float = 1.0
    ripple_phase_rad: float = 0.0
    drive_lag_s: float = 0.0
    reversal_deadband_m: float = 0.0

    def params(self) -> FloatArray:
        """The compiled plant's parameter vector."""
        p = np.zeros(_N_PLANT)
        p[_MASS], p[_OFFSET] = self.mass_kg, self.offset_N
        p[_FC_POS], p[_FC_NEG] = self.coulomb_pos_N, self.coulomb_neg_N
        p[_FV_POS], p[_FV_NEG] = self.viscous_pos_Ns_per_m, self.viscous_neg_Ns_per_m
        p[_STRIBECK_RATIO], p[_STRIBECK_V] = self.stribeck_ratio, self.stribeck_velocity_m_s
        p[_REV_AMP], p[_REV_LEN] = self.reversal_amplitude_N, self.reversal_length_m
        p[_RIPPLE_AMP], p[_RIPPLE_WL] = self.ripple_amplitude_N, self.ripple_wavelength_m
        p[_RIPPLE_PHASE], p[_LAG] = self.ripple_phase_rad, self.drive_lag_s
        p[_HAS_GMS] = 0.0 if self.gms is None else 1.0
        p[_REV_DEADBAND] = self.reversal_deadband_m
        return p

    def gms_kernel(self) -> Any:
        """A fresh GMS stream kernel (a placeholder when the model has no GMS)."""
        return _NO_GMS if self.gms is None else GmsStream(self.gms).kernel


@dataclass(frozen=True)
class LoopRun:
    """Signals of one run, one sample per servo cycle (at the cycle's start)."""

    time_s: FloatArray
    position_m: FloatArray
    velocity_m_s: FloatArray
    acceleration_m_s2: FloatArray
    command: FloatArray  # the drive command after saturation, disturbance included
    axis_force_N: FloatArray
    friction_N: FloatArray


@numba.njit(cache=True)
def _interp(t: float, times: FloatArray, values: FloatArray, cursor: FloatArray) -> float:
    """Piecewise-linear ``values(t)`` (held beyond the ends); ``cursor[0]`` remembers
    where the last call was, since the times asked for increase."""
    n = times.size
    if n == 1 or t <= times[0]:
        return values[0]
    if t >= times[n - 1]:
        return values[n - 1]
    i = int(cursor[0])
    while i > 0 and times[i] > t:
        i -= 1
    while times[i + 1] < t:
        i += 1
    cursor[0] = i
    w = (t - times[i]) / (times[i + 1] - times[i])
    return values[i] + w * (values[i + 1] - values[i])


@numba.njit(cache=True)
def _memoryless(p: FloatArray, q: float, v: float, gms_force: float) -> float:  # pragma: no cover
    """The friction parts evaluated at every RK4 stage (plus the held GMS force, scaled
    by the Stribeck factor at this stage's velocity)."""
    f = p[_OFFSET]
    if v > 0.0:
        f += p[_FC_POS] + p[_FV_POS] * v
    elif v < 0.0:
        f += -p[_FC_NEG] + p[_FV_NEG] * v
    if p[_RIPPLE_AMP] != 0.0:
        f += p[_RIPPLE_AMP] * math.sin(2.0 * math.pi * q / p[_RIPPLE_WL] + p[_RIPPLE_PHASE])
    if p[_HAS_GMS] != 0.0:
        u = v / p[_STRIBECK_V]
        f += gms_force * (1.0 + (p[_STRIBECK_RATIO] - 1.0) * math.exp(-u * u))
    return f


@numba.njit(cache=True)
def _reversal_step(
    path: FloatArray, q: float, v: float, deadband: float
) -> float:  # pragma: no cover
    """Advance the path to ``q``; return the direction of motion (0 before any).

    ``path = [started, last q, travel, direction, furthest q, travel there, travel at
    the last reversal]``: a reversal is a retreat of more than ``deadband`` from the
    furthest point reached, and counts from that point (as the catalogue's path)."""
    if path[0] != 0.0:
        path[2] += abs(q - path[1])
    path[0] = 1.0
    path[1] = q
    d = path[3]
    if d == 0.0:
        if v != 0.0:  # the first motion is no reversal: until one, no transient
            path[3] = 1.0 if v > 0.0 else -1.0
            path[4], path[5], path[6] = q, path[2], -np.inf
    elif (q - path[4]) * d >= 0.0:
        path[4], path[5] = q, path[2]
    elif (path[4] - q) * d > deadband:
        path[3] = -d
        path[6] = path[5]
        path[4], path[5] = q, path[2]
    return path[3]


@numba.njit(cache=True)
def _held(
    p: FloatArray, g: Any, truth: Pack, path: FloatArray, q: float, v: float
) -> tuple[float, float]:
    """The parts with memory, stepped once per sub-step: GMS force, reversal transient
    plus a friction truth (:mod:`sim.kernels`, e.g. the ball model)."""
    gms_force = gms_kernel.stream_step(g, q, v) if p[_HAS_GMS] != 0.0 else 0.0
    transient = truth_force(truth, q, v)
    if p[_REV_AMP] != 0.0:
        d = _reversal_step(path, q, v, p[_REV_DEADBAND])
        transient = p[_REV_AMP] * d * math.exp(-(path[2] - path[6]) / p[_REV_LEN])
    return gms_force, transient


@numba.njit(cache=True)
def _accel(p: FloatArray, q: float, v: float, force: float, gms_f: float, extra: float) -> float:
    return (force - _memoryless(p, q, v, gms_f) - extra) / p[_MASS]


@numba.njit(cache=True)
def _friction_along(
    plant: FloatArray, g: Any, truth: Pack, q: FloatArray, v: FloatArray, out: FloatArray
) -> None:  # pragma: no cover
    path = np.zeros(7)
    for i in range(q.size):
        gms_f, extra = _held(plant, g, truth, path, q[i], v[i])
        out[i] = _memoryless(plant, q[i], v[i], gms_f) + extra


def friction_along(
    model: RigidAxisModel, position_m: FloatArray, velocity_m_s: FloatArray
) -> FloatArray:
    """The model's friction (offset included) along a given motion, one sub-step per
    sample, from the virgin state: the force the plant feels, open loop."""
    out = np.zeros(len(position_m))
    _friction_along(
        model.params(), model.gms_kernel(), zero_truth(), np.ascontiguousarray(position_m, float),
        np.ascontiguousarray(velocity_m_s, float), out,
    )  # fmt: skip
    return out


@numba.njit(cache=True)
def run_position_loop(
    loop: FloatArray,
    plant: FloatArray,
    g: Any,
    truth: Pack,
    reference_m: FloatArray,
    feedforward: FloatArray,
    disturbance_t: FloatArray,
    disturbance: FloatArray,
    out: FloatArray,
) -> None:  # pragma: no cover
    """The whole run from rest at 0 m; ``out`` rows: position, velocity, acceleration,
    command, axis force, friction (one column per cycle).

    ``feedforward`` (command units) is added to the controller's output before the
    delay; ``disturbance`` (command units, piecewise linear in ``disturbance_t``)
    after the saturation.
    """
    period = loop[_T]
    kp, kv, gain, limit = loop[_KP], loop[_KV], loop[_GAIN], loop[_LIMIT]
    delay, nsub, ntaps = int(loop[_DELAY]), int(loop[_SUBSTEPS]), int(loop[_NTAPS])
    taps = loop[_TAPS : _TAPS + ntaps]
    lag = plant[_LAG]
    h = period / nsub
    history = np.zeros(ntaps)  # q(k), q(k-1), ...
    commands = np.zeros(delay + 1)  # ring of the controller's outputs
    cursor = np.zeros(1)
    path = np.zeros(7)
    q = v = 0.0
    axis_force = 0.0
    qf_prev = 0.0
    gms_f = extra = 0.0
    for k in range(reference_m.size):
        t0 = k * period
        for i in range(ntaps - 1, 0, -1):
            history[i] = history[i - 1]
        history[0] = q
        qf = 0.0
        for i in range(ntaps):
            qf += taps[i] * history[i]
        u_new = kv * (kp * (reference_m[k] - q) - (qf - qf_prev) / period) + feedforward[k]
        qf_prev = qf
        commands[k % (delay + 1)] = u_new
        applied = commands[(k - delay) % (delay + 1)] if k >= delay else 0.0
        held = min(max(applied, -limit), limit)
        command = held + _interp(t0, disturbance_t, disturbance, cursor)
        if lag == 0.0:
            axis_force = gain * command
        out[0, k], out[1, k], out[3, k], out[4, k] = q, v, command, axis_force
        out[2, k] = _accel(plant, q, v, axis_force, gms_f, extra)
        out[5, k] = _memoryless(plant, q, v, gms_f) + extra
        for j in range(nsub):
            ts = t0 + j * h
            gms_f, extra = _held(plant, g, truth, path, q, v)
            c1 = gain * (held + _interp(ts, disturbance_t, disturbance, cursor))
            c2 = gain * (held + _interp(ts + 0.5 * h, disturbance_t, disturbance, cursor))
            c3 = gain * (held + _interp(ts + h, disturbance_t, disturbance, cursor))
            if lag == 0.0:
                # q'' = a(q, q'): RK4 of the second-order system
                a1 = _accel(plant, q, v, c1, gms_f, extra)
                a2 = _accel(plant, q + 0.5 * h * v, v + 0.5 * h * a1, c2, gms_f, extra)
                qc = q + 0.5 * h * v + 0.25 * h * h * a1
                a3 = _accel(plant, qc, v + 0.5 * h * a2, c2, gms_f, extra)
                qd = q + h * v + 0.5 * h * h * a2
                a4 = _accel(plant, qd, v + h * a3, c3, gms_f, extra)
                q += h * v + h * h / 6.0 * (a1 + a2 + a3)
                v += h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
                axis_force = c3
            else:
                # states q, v, F with dF/dt = (command force - F) / lag
                b1 = (c1 - axis_force) / lag
                a1 = _accel(plant, q, v, axis_force, gms_f, extra)
                fa = axis_force + 0.5 * h * b1
                va = v + 0.5 * h * a1
                b2 = (c2 - fa) / lag
                a2 = _accel(plant, q + 0.5 * h * v, va, fa, gms_f, extra)
                fb = axis_force + 0.5 * h * b2
                vb = v + 0.5 * h * a2
                b3 = (c2 - fb) / lag
                a3 = _accel(plant, q + 0.5 * h * va, vb, fb, gms_f, extra)
                fc = axis_force + h * b3
                vc = v + h * a3
                b4 = (c3 - fc) / lag
                a4 = _accel(plant, q + h * vb, vc, fc, gms_f, extra)
                q += h / 6.0 * (v + 2.0 * va + 2.0 * vb + vc)
                v += h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
                axis_force += h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4)


def simulate_loop(
    loop: PositionLoop,
    model: RigidAxisModel,
    reference_m: FloatArray,
    feedforward: FloatArray | None = None,
    disturbance: tuple[FloatArray, FloatArray] | None = None,
    truth: Pack | None = None,
) -> LoopRun:
    """Run ``reference_m`` (one sample per cycle) once from rest.

    Parameters
    ----------
    loop
        The controller.
    model
        The plant: mass and friction.
    reference_m
        Reference position per cycle.
    feedforward
        Added to the controller output per cycle, in command units (default none).
    disturbance
        ``(time_s, value)``: a piecewise-linear signal in command units added after the
        saturation (default none), sampled at the integrator's stages.
    truth
        A friction truth's pack (:func:`sim.plant.compiled_truth`) added to the model's
        friction, stepped once per sub-step (default none).
    """
    n = reference_m.size
    ff = np.zeros(n) if feedforward is None else np.ascontiguousarray(feedforward, float)
    dist_t, dist = (np.zeros(1), np.zeros(1)) if disturbance is None else disturbance
    out = np.zeros((6, n))
    run_position_loop(
        loop.params(), model.params(), model.gms_kernel(),
        zero_truth() if truth is None else truth, np.ascontiguousarray(reference_m, float), ff,
        np.ascontiguousarray(dist_t, float), np.ascontiguousarray(dist, float), out,
    )  # fmt: skip
    return LoopRun(np.arange(n, dtype=np.float64) * loop.period_s, *out)
