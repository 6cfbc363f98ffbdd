"""The catalogue of measured-data effects, as extensions on top of a GMS friction force.

Each effect of ../shared/spec/measured-data.md is one module of this package: a frozen
dataclass holding its parameters (names and SI units as the spec gives them) and its form
(:mod:`.base` is the interface); how the diagnosis fits it is its policy
(:mod:`gms_comp.measured.policies`). :data:`CATALOGUE` registers them by name: adding an
effect is one module plus one line here. :mod:`.path` computes what an effect sees along
a trajectory; :mod:`.stream` applies a list of effects, batch or per sample.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import MISSING, fields
from typing import Any

from gms_comp.arrays import FloatArray
from gms_comp.errors import TableError
from gms_comp.runtime.effects.base import Effect, FilterEffect
from gms_comp.runtime.effects.direction_asymmetry import DirectionAsymmetry
from gms_comp.runtime.effects.drift import Drift
from gms_comp.runtime.effects.drive_lag import DriveLag
from gms_comp.runtime.effects.dwell_time import DwellTime
from gms_comp.runtime.effects.inertia import Inertia
from gms_comp.runtime.effects.offset import Offset
from gms_comp.runtime.effects.path import DEFAULT_STANDSTILL_SPEED_M_S, Context
from gms_comp.runtime.effects.position_ripple import PositionRipple
from gms_comp.runtime.effects.reversal_transient import ReversalTransient
from gms_comp.runtime.effects.sensor_lowpass import SensorLowpass
from gms_comp.runtime.effects.stream import ExtensionStream, apply_extensions
from gms_comp.runtime.effects.stribeck import Stribeck
from gms_comp.runtime.effects.viscous import Viscous

CATALOGUE: dict[str, type[Effect]] = {
    cls.name: cls
    for cls in (
        Viscous,
        Stribeck,
        DwellTime,
        PositionRipple,
        Offset,
        ReversalTransient,
        Drift,
        Inertia,
        SensorLowpass,
        DirectionAsymmetry,
        DriveLag,
    )
}

__all__ = [
    "CATALOGUE", "DEFAULT_STANDSTILL_SPEED_M_S", "Context", "DirectionAsymmetry", "Drift",
    "DriveLag", "DwellTime", "Effect", "ExtensionError", "ExtensionStream", "FilterEffect",
    "FloatArray", "Inertia", "Offset", "PositionRipple", "ReversalTransient",
    "SensorLowpass", "Stribeck", "Viscous", "apply_extensions", "effect_from_dict",
    "effect_to_dict",
]  # fmt: skip


class ExtensionError(TableError):
    """A table extension names an unknown effect or has the wrong parameters."""


def effect_from_dict(entry: Mapping[str, Any]) -> Effect:
    """Build an effect from ``{"effect": name, "parameters": {...}}`` (a table extension).

    Raises
    ------
    ExtensionError
        (a ``ValueError`` and a ``GmsCompError``) naming the entry's problem in one line.
    """
    name = entry.get("effect")
    if name not in CATALOGUE:
        raise ExtensionError(
            f"table extension: unknown effect {name!r} (known: {', '.join(CATALOGUE)})"
        )
    cls = CATALOGUE[name]
    params = entry.get("parameters")
    if not isinstance(params, Mapping):
        raise ExtensionError(f"table extension {name}: 'parameters' must be a table")
    wanted = {f.name for f in fields(cls)}
    required = {f.name for f in fields(cls) if f.default is MISSING}
    if not required <= set(params) <= wanted:
        raise ExtensionError(
            f"table extension {name}: parameters must be {sorted(required)}"
            + (f" (optional: {sorted(wanted - required)})" if wanted - required else "")
            + f", got {sorted(params)}"
        )
    values: dict[str, Any] = {}
    for key, value in params.items():
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not math.isfinite(value)
        ):
            raise ExtensionError(f"table extension {name}: parameter {key} must be a finite number")
        values[key] = int(value) if key == "order" else float(value)
    try:
        return cls(**values)
    except ValueError as exc:
        raise ExtensionError(f"table extension {name}: {exc}") from None


def effect_to_dict(effect: Effect) -> dict[str, Any]:
    """``{"effect": name, "parameters": {...}}``, as a table stores an extension."""
    return {"effect": effect.name, "parameters": effect.parameters()}
