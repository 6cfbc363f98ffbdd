"""Streaming friction observer: model force -> saturated, rate-limited feedforward current.

The observer runs a streaming friction model (the GMS table by default, with
the physical effects of its ``extensions``) once per servo cycle. It is fed
either reference samples, which the caller takes ``look_ahead`` cycles ahead
to cancel the transport and current-loop delays, or the measured position and
velocity. The force becomes a current through the
motor's force constant, scaled by the friction level, clipped to a current
limit and rate-limited so that a model fault cannot kick the axis.

States: enabled, or disabled (the output ramps to 0 A at the rate limit while
the model keeps tracking, so re-enabling is bumpless). A non-finite model force
disables the observer by itself (fallback).

Optional slow adaptation of the friction level: during steady motion the
friction share of the drive's current, ``k_f (i_drive - i_inertial)``, is
compared with the model force and the level follows their ratio with a small
gain. Guards against drift: updates only above a minimum speed and with a model
force clear of zero, outlying ratios are ignored, and the level stays within
bounds around its initial value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal, Protocol, runtime_checkable

import numba
import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.config import in_range, non_negative, positive
from gms_comp.errors import TableError
from gms_comp.gms import GmsStream
from gms_comp.runtime.effects import (
    DEFAULT_STANDSTILL_SPEED_M_S,
    Effect,
    ExtensionStream,
    effect_from_dict,
)
from gms_comp.tables.table import GmsTable


@runtime_checkable
class ForceModel(Protocol):
    """A streaming friction model: resisting force in N (``F v >= 0`` when sliding)."""

    def reset(self) -> None:
        """Back to the virgin state."""

    def step(self, position_m: float, velocity_m_s: float) -> float:
        """Advance to ``position_m`` and return the force."""
        ...


def physical_extensions(table: GmsTable) -> list[Effect]:
    """A table's extensions that act on the contact: the measurement chain's (those
    flagged ``measurement_only``: sensor filter, drive lag, inertia) a compensator must
    not add."""
    built = (
        effect_from_dict({"effect": e.effect, "parameters": e.parameters}) for e in table.extensions
    )
    return [e for e in built if not e.measurement_only]


class ExtendedGms:
    """A table's GMS model followed by its physical extensions (``gms_comp.runtime.effects``).

    The extensions need time and acceleration; both follow from the samples, one
    per servo cycle.
    """

    def __init__(self, table: GmsTable, servo_period_s: float) -> None:
        self.gms = GmsStream(table.params)
        context = dict(table.extension_context or {})
        self.extensions = ExtensionStream(
            physical_extensions(table), servo_period_s,
            context.get("standstill_speed_m_s", DEFAULT_STANDSTILL_SPEED_M_S),
            context.get("reversal_deadband_m", 0.0), context.get("rest_band_m", 0.0),
            gms=table.params,
        )  # fmt: skip
        self.servo_period_s = servo_period_s
        self.reset()

    def reset(self) -> None:
        """Virgin model and path."""
        self.gms.reset()
        self.extensions.reset()
        self._cycle = 0
        self._last_velocity_m_s = 0.0

    def step(self, position_m: float, velocity_m_s: float) -> float:
        """GMS force with the extensions applied."""
        acceleration = (velocity_m_s - self._last_velocity_m_s) / self.servo_period_s
        self._last_velocity_m_s = velocity_m_s
        time_s = self._cycle * self.servo_period_s
        self._cycle += 1
        force = self.gms.step(position_m, velocity_m_s)
        return self.extensions.step(time_s, position_m, velocity_m_s, acceleration, force)


def table_model(table: GmsTable, servo_period_s: float) -> ForceModel:
    """The streaming model of a table: plain GMS, or GMS with its extensions."""
    if physical_extensions(table):
        return ExtendedGms(table, servo_period_s)
    return GmsStream(table.params)


def check_table_fits(
    table: GmsTable, where: str, force_constant_N_per_A: float, level: float, current_limit_A: float
) -> None:
    """Refuse a table whose sliding force needs more than the feedforward's current limit.

    A table holds the whole axis's friction (:mod:`gms_comp.tables.table`); one that does
    not fit was made for another axis, or is a table of another meaning.

    Raises
    ------
    TableError
        With the force, the current it needs and the limit.
    """
    force_N = level * table.params.slip_level * float(np.sum(table.params.limit_N))
    needed_A = force_N / force_constant_N_per_A
    if needed_A > current_limit_A:
        raise TableError(
            where,
            "limit_N",
            f"the table's sliding force {force_N:.4g} N (the whole axis's friction, times "
            f"level {level:g}) needs {needed_A:.4g} A at {force_constant_N_per_A:g} N/A, more "
            f"than compensator.current_limit_A = {current_limit_A:g} A",
        )


@dataclass(frozen=True)
class CompensatorConfig:
    """The ``[compensator]`` section: how the feedforward is computed and limited.

    ``table_path``: a table of the whole axis's friction, physics or diagnosed, run as it
    stands (times ``friction_level_scale``); one that needs more than ``current_limit_A``
    is refused.
    """

    feed: Literal["reference", "measured"] = "reference"
    look_ahead_cycles: int = field(default=1, metadata=in_range(0, 1000))
    table_path: str = ""
    friction_level_scale: float = field(default=1.0, metadata=positive(100.0))
    current_limit_A: float = field(default=3.0, metadata=in_range(1e-3, 1e3))
    rate_limit_A_per_s: float = field(default=2000.0, metadata=positive(1e7))
    coulomb_velocity_band_m_s: float = field(default=1e-4, metadata=positive(1.0))
    adaptation_rate_per_s: float = field(default=0.0, metadata=non_negative(1e4))
    adaptation_min_velocity_m_s: float = field(default=2e-3, metadata=positive(10.0))
    adaptation_max_inertial_share: float = field(default=0.3, metadata=positive(1.0))
    adaptation_level_bounds: tuple[float, ...] = field(
        default=(0.5, 2.0), metadata=positive(100.0, max_items=8)
    )

    def problems(self) -> list[tuple[str, str]]:
        """`adaptation_level_bounds` is `[lo, hi]` with 0 < lo <= 1 <= hi."""
        lo_hi = self.adaptation_level_bounds
        if len(lo_hi) != 2 or not 0 < lo_hi[0] <= 1.0 <= lo_hi[1]:
            return [
                (
                    "adaptation_level_bounds",
                    f"must be [lo, hi] with 0 < lo <= 1 <= hi, got {list(lo_hi)}",
                )
            ]
        return []


# Layout of the observer's state and parameter vectors (the compiled functions').
_OUTPUT, _LEVEL, _ENABLED, _FORCE, _INITIAL = range(5)
_KF, _LIMIT, _MAX_STEP, _GAIN, _MIN_V, _LO, _HI, _SHARE = range(8)
PARAMS = 8


@numba.njit(cache=True)
def feedforward_current(
    state: FloatArray, params: FloatArray, force_N: float
) -> float:  # pragma: no cover
    """Saturated, rate-limited current for a model force; a non-finite force disables.

    ``state = [output A, level, enabled, model force N, initial level]``,
    ``params = [k_f, current limit, max step per cycle, adaptation gain per cycle,
    min velocity, level bounds lo, hi, max inertial share]``.
    """
    if not math.isfinite(force_N):
        state[_ENABLED] = 0.0
        force_N = 0.0
    state[_FORCE] = force_N
    limit = params[_LIMIT]
    target = state[_LEVEL] * force_N / params[_KF] if state[_ENABLED] != 0.0 else 0.0
    target = min(max(target, -limit), limit)
    step = params[_MAX_STEP]
    state[_OUTPUT] += min(max(target - state[_OUTPUT], -step), step)
    return state[_OUTPUT]


@numba.njit(cache=True)
def adapt_level(
    state: FloatArray,
    params: FloatArray,
    drive_current_A: float,
    inertial_current_A: float,
    velocity_m_s: float,
) -> None:  # pragma: no cover
    """Nudge the level towards the drive's current (see :meth:`FrictionObserver.adapt`).

    Frozen where friction cannot be seen: below the minimum speed, where the model does
    not slide the way the axis moves (presliding after a reversal, a model force at 0),
    where the mass takes more than the inertial share of the model's friction current
    (acceleration), and for a ratio outside half to twice the level (an outlier)."""
    if params[_GAIN] == 0.0 or not abs(velocity_m_s) >= params[_MIN_V]:
        return
    model_force = state[_FORCE]
    level = state[_LEVEL]
    if not model_force * velocity_m_s > 0.0:
        return
    model_A = model_force / params[_KF]
    if not abs(inertial_current_A) <= params[_SHARE] * level * abs(model_A):
        return
    ratio = (drive_current_A - inertial_current_A) / model_A
    if not 0.5 * level < ratio < 2.0 * level:
        return  # an outlier (a reversal transient, a collision): no evidence of level
    lo, hi = params[_LO] * state[_INITIAL], params[_HI] * state[_INITIAL]
    state[_LEVEL] = min(max(level + params[_GAIN] * (ratio - level), lo), hi)


class FrictionObserver:
    """Feedforward current from a streaming friction model.

    Parameters
    ----------
    table
        A GMS table (its physical extensions applied), or any :class:`ForceModel`.
    force_constant_N_per_A
        Motor force constant; current = level * force / k_f.
    servo_period_s
        One cycle; sets the per-cycle step of the rate limit and the adaptation.
    level
        Friction level: multiplies the model force (``friction_level_scale``: a
        deliberately mis-set level; a table already holds the whole axis's friction).
    config
        Limits and adaptation settings.

    The limits and the adaptation are compiled functions on the ``state`` and
    ``params`` arrays (:func:`feedforward_current`, :func:`adapt_level`), which a
    compiled control loop can call directly.

    Examples
    --------
    >>> import numpy as np
    >>> from gms_comp.gms import GmsParams
    >>> obs = FrictionObserver(GmsStream(GmsParams(np.array([1e6]), np.array([10.0]))),
    ...                        force_constant_N_per_A=50.0, servo_period_s=2.5e-4)
    >>> [round(obs.step(x, 1e-3), 3) for x in (0.0, 1e-3, 2e-3)]
    [0.0, 0.2, 0.2]
    """

    def __init__(
        self,
        table: GmsTable | ForceModel,
        force_constant_N_per_A: float,
        servo_period_s: float,
        level: float = 1.0,
        config: CompensatorConfig | None = None,
    ) -> None:
        self.model = table if isinstance(table, ForceModel) else table_model(table, servo_period_s)
        cfg = self.config = config or CompensatorConfig()
        self.force_constant_N_per_A = force_constant_N_per_A
        self.servo_period_s = servo_period_s
        lo, hi = cfg.adaptation_level_bounds
        self.params = np.array(
            [
                force_constant_N_per_A,
                cfg.current_limit_A,
                cfg.rate_limit_A_per_s * servo_period_s,
                min(1.0, cfg.adaptation_rate_per_s * servo_period_s),
                cfg.adaptation_min_velocity_m_s,
                lo,
                hi,
                cfg.adaptation_max_inertial_share,
            ]
        )
        self.state = np.array([0.0, level, 1.0, 0.0, level])
        self.reset()
        self.step(0.0, 0.0)  # the kernels load now, not in a real-time loop's first cycle
        self.reset()

    @property
    def initial_level(self) -> float:
        """The level set at construction."""
        return float(self.state[_INITIAL])

    @property
    def level(self) -> float:
        """The friction level now (adaptation moves it)."""
        return float(self.state[_LEVEL])

    @property
    def enabled(self) -> bool:
        """False while falling back to no feedforward."""
        return bool(self.state[_ENABLED])

    @property
    def model_force_N(self) -> float:
        """The model force of the last step."""
        return float(self.state[_FORCE])

    @property
    def output_A(self) -> float:
        """The feedforward current of the last step."""
        return float(self.state[_OUTPUT])

    def reset(self) -> None:
        """Virgin model, 0 A output, enabled, level back to its initial value."""
        self.model.reset()
        self.state[:] = [0.0, self.initial_level, 1.0, 0.0, self.initial_level]

    def disable(self) -> None:
        """Fall back to no feedforward; the output ramps down at the rate limit."""
        self.state[_ENABLED] = 0.0

    def enable(self) -> None:
        """Resume feedforward (bumpless: the model kept tracking)."""
        self.state[_ENABLED] = 1.0

    def step(self, position_m: float, velocity_m_s: float) -> float:
        """Advance the model one cycle and return the feedforward current in A."""
        force = self.model.step(position_m, velocity_m_s)
        return float(feedforward_current(self.state, self.params, force))

    def adapt(self, drive_current_A: float, inertial_current_A: float, velocity_m_s: float) -> None:
        """Nudge the friction level towards what the drive's current says.

        ``drive_current_A`` is the motor current, ``inertial_current_A`` the share
        that accelerates the mass (``m a / k_f`` from the reference), ``velocity_m_s``
        the measured velocity (a stuck axis shows none). Guards (:func:`adapt_level`):
        only above the minimum speed, with the model sliding the way the axis moves,
        while the inertial current stays below ``adaptation_max_inertial_share`` of the
        model's friction current, for ratios within a factor 2 of the level, and the
        level within its bounds times the initial level. docs/adaptation.md gives the
        stability bound.
        """
        adapt_level(self.state, self.params, drive_current_A, inertial_current_A, velocity_m_s)
