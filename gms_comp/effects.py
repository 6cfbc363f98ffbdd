"""The catalogue of measured-data effects, as extensions on top of a GMS friction force.

Each effect of ../shared/spec/measured-data.md is a frozen dataclass holding its
parameters (names and SI units as the spec gives them). An additive effect is a linear
combination of *basis* columns whose shape depends on a few nonlinear parameters (the
ripple's wavelength, the transient's length, ...): ``force + basis(ctx) @ coefficients``.
The diagnosis fits the coefficients by least squares over those same columns, so a fitted
effect and the one applied afterwards are one formula. ``sensor_lowpass`` is the one
effect that is a filter of the whole force instead.

The forms that scale the friction (stribeck, dwell_time, drift) act on the GMS force
``ctx.gms_force_N``: in steady sliding a GMS force equals its element limits times the
velocity level, so scaling the force is scaling the limits; at a break-away it scales the
peak. That keeps the GMS kernel (:mod:`gms_comp.gms`) untouched.

Path quantities (direction, distance since the last reversal, length of the last
standstill, distance since the motion resumed) come from one numba per-sample routine
that serves both the batch :class:`Context` and the streaming :class:`ExtensionStream`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, fields
from typing import Any, ClassVar

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal

FloatArray = NDArray[np.float64]

# Below this speed an axis counts as standing still unless a caller says otherwise.
DEFAULT_STANDSTILL_SPEED_M_S = 1e-4

# --- path quantities ----------------------------------------------------------------------

# A standstill ends once the speed exceeds this multiple of the standstill speed.
RESUME_FACTOR = 2.0

# Layout of the path-state vector.
(_FIRST, _PREV_X, _CUM, _DIR, _CUM_AT_REVERSAL, _STILL, _STILL_SINCE, _DWELL, _CUM_AT_RESUME,
 _T0, _EXTREME, _CUM_AT_EXTREME, _N_STATE) = range(13)  # fmt: skip
# Layout of one output row.
_OUT_DIR, _OUT_S_REV, _OUT_DWELL, _OUT_S_START, _OUT_MOVING, _OUT_ELAPSED, _N_OUT = range(7)


@numba.njit(cache=True)
def _direction_step(state: FloatArray, x: float, v: float, deadband: float) -> None:
    """Direction of motion from the position: a reversal is a retreat of more than
    ``deadband`` from the furthest point reached, and counts from that turning point
    (so encoder steps and filter ringing at a standstill make no reversals)."""
    d = state[_DIR]
    if d == 0.0:
        if v != 0.0:  # the first motion sets the direction; distances count from here
            state[_DIR] = 1.0 if v > 0.0 else -1.0
            state[_EXTREME] = x
            state[_CUM_AT_EXTREME] = state[_CUM]
            state[_CUM_AT_REVERSAL] = state[_CUM]
    elif (x - state[_EXTREME]) * d >= 0.0:
        state[_EXTREME] = x
        state[_CUM_AT_EXTREME] = state[_CUM]
    elif (state[_EXTREME] - x) * d > deadband:
        state[_DIR] = -d
        state[_CUM_AT_REVERSAL] = state[_CUM_AT_EXTREME]
        state[_EXTREME] = x
        state[_CUM_AT_EXTREME] = state[_CUM]


@numba.njit(cache=True)
def _path_step(
    state: FloatArray, t: float, x: float, v: float, still_speed: float, deadband: float,
    out: FloatArray,
) -> None:  # fmt: skip
    first = state[_FIRST] == 1.0
    dx = 0.0 if first else x - state[_PREV_X]
    state[_CUM] += abs(dx)
    _direction_step(state, x, v, deadband)
    # hysteresis: a noisy speed near the threshold must not make many short standstills
    still = abs(v) < (RESUME_FACTOR * still_speed if state[_STILL] == 1.0 else still_speed)
    if first:
        state[_T0] = t
    if still and (first or state[_STILL] == 0.0):
        state[_STILL_SINCE] = t
    if not still and not first and state[_STILL] == 1.0:
        state[_DWELL] = t - state[_STILL_SINCE]
        state[_CUM_AT_RESUME] = state[_CUM]
    state[_STILL] = 1.0 if still else 0.0
    state[_PREV_X] = x
    state[_FIRST] = 0.0
    out[_OUT_DIR] = state[_DIR]
    out[_OUT_S_REV] = state[_CUM] - state[_CUM_AT_REVERSAL]
    out[_OUT_DWELL] = state[_DWELL]
    out[_OUT_S_START] = state[_CUM] - state[_CUM_AT_RESUME]
    out[_OUT_MOVING] = 0.0 if still else 1.0
    out[_OUT_ELAPSED] = t - state[_T0]


@numba.njit(cache=True)
def _path_run(
    state: FloatArray, t: FloatArray, x: FloatArray, v: FloatArray, still_speed: float,
    deadband: float,
) -> FloatArray:  # fmt: skip
    out = np.empty((t.size, _N_OUT))
    for i in range(t.size):
        _path_step(state, t[i], x[i], v[i], still_speed, deadband, out[i])
    return out


def _fresh_path_state() -> FloatArray:
    state = np.zeros(_N_STATE)
    state[_FIRST] = 1.0
    return state


@dataclass(frozen=True)
class Context:
    """What an effect sees along a trajectory (arrays of one length, or 1-element arrays
    for one streaming sample)."""

    time_s: FloatArray
    position_m: FloatArray
    velocity_m_s: FloatArray
    acceleration_m_s2: FloatArray
    gms_force_N: FloatArray
    direction: FloatArray
    distance_since_reversal_m: FloatArray
    dwell_s: FloatArray
    distance_since_start_m: FloatArray
    moving: FloatArray
    elapsed_s: FloatArray
    sample_time_s: float

    @classmethod
    def along(
        cls,
        time_s: ArrayLike,
        position_m: ArrayLike,
        velocity_m_s: ArrayLike,
        acceleration_m_s2: ArrayLike,
        gms_force_N: ArrayLike,
        standstill_speed_m_s: float = DEFAULT_STANDSTILL_SPEED_M_S,
        reversal_deadband_m: float = 0.0,
    ) -> Context:
        """The context of a whole trajectory (a reversal needs a retreat of more than
        ``reversal_deadband_m``: set it above the position noise)."""
        t = np.ascontiguousarray(time_s, dtype=np.float64)
        x = np.ascontiguousarray(position_m, dtype=np.float64)
        v = np.ascontiguousarray(velocity_m_s, dtype=np.float64)
        path = _path_run(_fresh_path_state(), t, x, v, standstill_speed_m_s, reversal_deadband_m)
        dt = float((t[-1] - t[0]) / (t.size - 1)) if t.size > 1 else 0.0
        return cls._with_path(
            t, x, v, np.asarray(acceleration_m_s2, float), np.asarray(gms_force_N, float), path, dt
        )

    @classmethod
    def _with_path(
        cls, t: FloatArray, x: FloatArray, v: FloatArray, a: FloatArray, f: FloatArray,
        path: FloatArray, sample_time_s: float,
    ) -> Context:  # fmt: skip
        return cls(
            t, x, v, a, f,
            direction=path[:, _OUT_DIR],
            distance_since_reversal_m=path[:, _OUT_S_REV],
            dwell_s=path[:, _OUT_DWELL],
            distance_since_start_m=path[:, _OUT_S_START],
            moving=path[:, _OUT_MOVING],
            elapsed_s=path[:, _OUT_ELAPSED],
            sample_time_s=sample_time_s,
        )  # fmt: skip


# --- the catalogue -------------------------------------------------------------------------


@dataclass(frozen=True)
class Effect:
    """Base of the catalogue: ``force + basis(ctx, shape) @ coefficients``.

    Subclasses name their nonlinear shape parameters in ``SHAPE`` and map between the
    fitted coefficients and their named parameters.
    """

    name: ClassVar[str]
    SHAPE: ClassVar[tuple[str, ...]] = ()
    # An effect of the measurement chain, not of the contact: a compensator does not add it.
    measurement_only: ClassVar[bool] = False

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        raise NotImplementedError

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        raise NotImplementedError

    def coefficients(self) -> FloatArray:
        raise NotImplementedError

    def shape(self) -> dict[str, float]:
        return {k: getattr(self, k) for k in self.SHAPE}

    def parameters(self) -> dict[str, float]:
        return {k: float(v) for k, v in asdict(self).items()}

    def apply(self, ctx: Context, force_N: FloatArray) -> FloatArray:
        """The measured force this effect makes of ``force_N`` (batch)."""
        return force_N + self.basis(ctx, self.shape()) @ self.coefficients()


@dataclass(frozen=True)
class Viscous(Effect):
    name: ClassVar[str] = "viscous"
    c_Ns_per_m: float

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        return ctx.velocity_m_s[:, None]

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        return cls(float(coefficients[0]))

    def coefficients(self) -> FloatArray:
        return np.array([self.c_Ns_per_m])


@dataclass(frozen=True)
class Stribeck(Effect):
    name: ClassVar[str] = "stribeck"
    SHAPE: ClassVar[tuple[str, ...]] = ("v_s_m_per_s",)
    ratio: float
    v_s_m_per_s: float

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        u = ctx.velocity_m_s / shape["v_s_m_per_s"]
        return (ctx.gms_force_N * np.exp(-(u * u)))[:, None]

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        return cls(1.0 + float(coefficients[0]), shape["v_s_m_per_s"])

    def coefficients(self) -> FloatArray:
        return np.array([self.ratio - 1.0])


@dataclass(frozen=True)
class DwellTime(Effect):
    """Break-away force raised by 1 + gamma ln(1 + t_d/tau) until ``breakaway_m`` of
    travel after the standstill (then the elements slip and the gain is gone)."""

    name: ClassVar[str] = "dwell_time"
    SHAPE: ClassVar[tuple[str, ...]] = ("tau_s", "breakaway_m")
    gamma: float
    tau_s: float
    breakaway_m: float

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        window = ctx.moving * (ctx.distance_since_start_m < shape["breakaway_m"])
        gain = np.log1p(ctx.dwell_s / shape["tau_s"])
        return (ctx.gms_force_N * gain * window)[:, None]

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        return cls(float(coefficients[0]), shape["tau_s"], shape["breakaway_m"])

    def coefficients(self) -> FloatArray:
        return np.array([self.gamma])


@dataclass(frozen=True)
class PositionRipple(Effect):
    name: ClassVar[str] = "position_ripple"
    SHAPE: ClassVar[tuple[str, ...]] = ("wavelength_m",)
    amplitude_N: float
    wavelength_m: float
    phase_rad: float

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        arg = 2 * np.pi * ctx.position_m / shape["wavelength_m"]
        return np.column_stack([np.sin(arg), np.cos(arg)])

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        a, b = (float(c) for c in coefficients)
        # a sin + b cos = A sin(arg + phi)
        return cls(math.hypot(a, b), shape["wavelength_m"], math.atan2(b, a))

    def coefficients(self) -> FloatArray:
        return self.amplitude_N * np.array([math.cos(self.phase_rad), math.sin(self.phase_rad)])


@dataclass(frozen=True)
class Offset(Effect):
    name: ClassVar[str] = "offset"
    offset_N: float

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        return np.ones((len(ctx.time_s), 1))

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        return cls(float(coefficients[0]))

    def coefficients(self) -> FloatArray:
        return np.array([self.offset_N])


@dataclass(frozen=True)
class ReversalTransient(Effect):
    name: ClassVar[str] = "reversal_transient"
    SHAPE: ClassVar[tuple[str, ...]] = ("length_m",)
    amplitude_N: float
    length_m: float

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        decay = np.exp(-ctx.distance_since_reversal_m / shape["length_m"])
        return (ctx.direction * decay)[:, None]

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        return cls(float(coefficients[0]), shape["length_m"])

    def coefficients(self) -> FloatArray:
        return np.array([self.amplitude_N])


@dataclass(frozen=True)
class Drift(Effect):
    name: ClassVar[str] = "drift"
    SHAPE: ClassVar[tuple[str, ...]] = ("tau_s",)
    kappa: float
    tau_s: float

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        return (ctx.gms_force_N * -np.expm1(-ctx.elapsed_s / shape["tau_s"]))[:, None]

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        return cls(float(coefficients[0]), shape["tau_s"])

    def coefficients(self) -> FloatArray:
        return np.array([self.kappa])


@dataclass(frozen=True)
class Inertia(Effect):
    name: ClassVar[str] = "inertia"
    # the acceleration feedforward already supplies the inertial force
    measurement_only: ClassVar[bool] = True
    mass_kg: float

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        return ctx.acceleration_m_s2[:, None]

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        return cls(float(coefficients[0]))

    def coefficients(self) -> FloatArray:
        return np.array([self.mass_kg])


@dataclass(frozen=True)
class DirectionAsymmetry(Effect):
    """Viscous friction that differs by direction (an extension beyond the spec's
    catalogue): dF = c_diff |v| / 2, so the slope is c + c_diff/2 moving forward and
    c - c_diff/2 moving back (EMPS: a fatigued screw, Janot et al. 2019, §4.2)."""

    name: ClassVar[str] = "direction_asymmetry"
    c_diff_Ns_per_m: float

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        return 0.5 * np.abs(ctx.velocity_m_s)[:, None]

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        return cls(float(coefficients[0]))

    def coefficients(self) -> FloatArray:
        return np.array([self.c_diff_Ns_per_m])


@dataclass(frozen=True)
class FilterEffect(Effect):
    """An effect that is a linear filter of the whole force (applied after the others)."""

    def filter(self, sample_time_s: float) -> tuple[FloatArray, FloatArray]:
        raise NotImplementedError

    def apply(self, ctx: Context, force_N: FloatArray) -> FloatArray:
        return self.filter_columns(force_N, ctx.sample_time_s)

    def filter_columns(self, x: FloatArray, sample_time_s: float) -> FloatArray:
        """Filter along axis 0, starting at rest at the first sample's value."""
        b, a = self.filter(sample_time_s)
        zi = signal.lfilter_zi(b, a)
        x0 = x[0]
        zi_full = np.multiply.outer(zi, x0) if np.ndim(x0) else zi * x0
        y, _ = signal.lfilter(b, a, x, axis=0, zi=zi_full)
        return np.asarray(y)


@dataclass(frozen=True)
class SensorLowpass(FilterEffect):
    """The sensor reports a causal Butterworth low-pass of the true force."""

    name: ClassVar[str] = "sensor_lowpass"
    measurement_only: ClassVar[bool] = True
    cutoff_Hz: float
    order: int

    def filter(self, sample_time_s: float) -> tuple[FloatArray, FloatArray]:
        nyquist_Hz = 0.5 / sample_time_s
        b, a = signal.butter(self.order, min(self.cutoff_Hz / nyquist_Hz, 0.99))
        return np.asarray(b), np.asarray(a)

    def parameters(self) -> dict[str, float]:
        return {"cutoff_Hz": float(self.cutoff_Hz), "order": int(self.order)}


@dataclass(frozen=True)
class DriveLag(FilterEffect):
    """The axis force follows the drive command with a first-order lag ``lag_s`` (current
    loop, motor inductance), so the recorded command leads the force: command =
    force + lag_s dforce/dt (backward difference). An extension beyond the spec's
    catalogue, for drive-force traces only."""

    name: ClassVar[str] = "drive_lag"
    measurement_only: ClassVar[bool] = True
    lag_s: float

    def filter(self, sample_time_s: float) -> tuple[FloatArray, FloatArray]:
        r = self.lag_s / sample_time_s
        return np.array([1.0 + r, -r]), np.array([1.0])


CATALOGUE: dict[str, type[Effect]] = {
    cls.name: cls
    for cls in (
        Viscous, Stribeck, DwellTime, PositionRipple, Offset, ReversalTransient, Drift,
        Inertia, SensorLowpass, DirectionAsymmetry, DriveLag,
    )
}  # fmt: skip


def effect_from_dict(entry: Mapping[str, Any]) -> Effect:
    """Build an effect from ``{"effect": name, "parameters": {...}}`` (a table extension).

    Raises ``ValueError`` naming the entry's problem (the table reader wraps it).
    """
    name = entry.get("effect")
    if name not in CATALOGUE:
        raise ValueError(f"unknown effect {name!r} (known: {', '.join(CATALOGUE)})")
    cls = CATALOGUE[name]
    params = entry.get("parameters")
    if not isinstance(params, Mapping):
        raise ValueError(f"effect {name}: 'parameters' must be a table")
    wanted = {f.name for f in fields(cls)}
    if set(params) != wanted:
        raise ValueError(
            f"effect {name}: parameters must be {sorted(wanted)}, got {sorted(params)}"
        )
    values: dict[str, Any] = {}
    for key, value in params.items():
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not math.isfinite(value)
        ):
            raise ValueError(f"effect {name}: parameter {key} must be a finite number")
        values[key] = int(value) if key == "order" else float(value)
    return cls(**values)


def effect_to_dict(effect: Effect) -> dict[str, Any]:
    return {"effect": effect.name, "parameters": effect.parameters()}


def apply_extensions(extensions: Sequence[Effect], ctx: Context) -> FloatArray:
    """The measured force: the GMS force plus every additive effect, then any filter."""
    force = ctx.gms_force_N.copy()
    for effect in extensions:
        if not isinstance(effect, FilterEffect):
            force = effect.apply(ctx, force)
    for effect in extensions:
        if isinstance(effect, FilterEffect):
            force = effect.apply(ctx, force)
    return force


class ExtensionStream:
    """Per-sample application of a list of effects, equal to :func:`apply_extensions`."""

    def __init__(
        self,
        extensions: Sequence[Effect],
        sample_time_s: float,
        standstill_speed_m_s: float = DEFAULT_STANDSTILL_SPEED_M_S,
        reversal_deadband_m: float = 0.0,
    ) -> None:
        self.extensions = tuple(extensions)
        self.sample_time_s = sample_time_s
        self.standstill_speed_m_s = standstill_speed_m_s
        self.reversal_deadband_m = reversal_deadband_m
        self._filters = [
            e.filter(sample_time_s) for e in self.extensions if isinstance(e, FilterEffect)
        ]
        self.reset()

    def reset(self) -> None:
        self._path = _fresh_path_state()
        self._row = np.empty((1, _N_OUT))
        self._zi: list[FloatArray] | None = None

    def step(
        self,
        time_s: float,
        position_m: float,
        velocity_m_s: float,
        acceleration_m_s2: float,
        gms_force_N: float,
    ) -> float:
        """The extended force for one sample."""
        _path_step(self._path, time_s, position_m, velocity_m_s, self.standstill_speed_m_s,
                   self.reversal_deadband_m, self._row[0])  # fmt: skip
        ctx = Context._with_path(
            np.array([time_s]), np.array([position_m]), np.array([velocity_m_s]),
            np.array([acceleration_m_s2]), np.array([gms_force_N]), self._row,
            self.sample_time_s,
        )  # fmt: skip
        force = gms_force_N
        for effect in self.extensions:
            if not isinstance(effect, FilterEffect):
                force = float(effect.apply(ctx, np.array([force]))[0])
        if self._zi is None:  # start at rest at the first value, as the batch filter does
            self._zi = [signal.lfilter_zi(b, a) * force for b, a in self._filters]
        for i, (b, a) in enumerate(self._filters):
            y, self._zi[i] = signal.lfilter(b, a, [force], zi=self._zi[i])
            force = float(y[0])
        return force
