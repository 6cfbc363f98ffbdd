"""The catalogue of measured-data effects, as extensions on top of a GMS friction force.

Each effect of ../shared/spec/measured-data.md is one module of this package: a frozen
dataclass holding its parameters (names and SI units as the spec gives them) and its form
(:mod:`.base` is the interface); how the diagnosis fits it is its policy
(:mod:`gms_comp.measured.policies`). :data:`CATALOGUE` registers them by name: adding an
effect is one module plus one line here. :mod:`.path` computes what an effect sees along
a trajectory; :mod:`.stream` applies a list of effects, batch or per sample.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import MISSING, fields
from typing import Any

from gms_comp.arrays import FloatArray
from gms_comp.config import field_range
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
from gms_comp.tables.table import GmsTable
from gms_comp.validation import finite_float, shown

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
    "SensorLowpass", "Stribeck", "Viscous", "apply_extensions", "check_extensions",
    "effect_from_dict", "effect_to_dict",
]  # fmt: skip


class ExtensionError(TableError):
    """A table extension names an unknown effect or has the wrong parameters."""


def effect_from_dict(
    entry: Mapping[str, Any], source: str = "table extension", key: str = "extensions"
) -> Effect:
    """Build an effect from ``{"effect": name, "parameters": {...}}`` (a table extension).

    Each parameter is checked against the range its effect declares (the field's
    ``in_range``/``positive`` metadata) before the effect is made.

    Parameters
    ----------
    entry
        The extension as a table stores it.
    source, key
        The file and the extension's field (``extensions.2``) the refusal names.

    Raises
    ------
    ExtensionError
        (a ``ValueError`` and a ``GmsCompError``) naming the entry's problem in one line.
    """
    name = entry.get("effect")
    if name not in CATALOGUE:
        raise ExtensionError(
            source,
            f"{key}.effect",
            f"unknown effect {shown(name)} (known: {', '.join(CATALOGUE)})",
        )
    cls = CATALOGUE[name]
    params = entry.get("parameters")
    if not isinstance(params, Mapping):
        raise ExtensionError(source, f"{key}.parameters", f"{name}: must be a table")
    declared = {f.name: f for f in fields(cls)}
    required = {n for n, f in declared.items() if f.default is MISSING}
    if not required <= set(params) <= set(declared):
        raise ExtensionError(
            source,
            f"{key}.parameters",
            f"{name}: parameters must be {sorted(required)}"
            + (
                f" (optional: {sorted(set(declared) - required)})"
                if set(declared) - required
                else ""
            )
            + f", got {sorted(params)}",
        )
    values: dict[str, Any] = {}
    for param, value in params.items():
        where = f"{key}.parameters.{param}"
        number = finite_float(value)
        if number is None:
            raise ExtensionError(source, where, f"must be a finite number, got {shown(value)}")
        bounds = field_range(declared[param])
        if bounds is not None and not bounds.contains(value):
            raise ExtensionError(source, where, f"must be in {bounds}, got {shown(value)}")
        if declared[param].type in (int, "int"):
            if not number.is_integer():
                raise ExtensionError(source, where, f"must be an integer, got {shown(value)}")
            values[param] = int(number)
        else:
            values[param] = number
    try:
        return cls(**values)
    except ValueError as exc:
        raise ExtensionError(source, key, f"{name}: {exc}") from None


def check_extensions(table: GmsTable, source: str) -> tuple[Effect, ...]:
    """Every extension of ``table`` as its effect, each checked against its declared
    parameters and ranges; a refusal names ``source`` and the extension's field."""
    return tuple(
        effect_from_dict(
            {"effect": e.effect, "parameters": e.parameters}, source, f"extensions.{i}"
        )
        for i, e in enumerate(table.extensions)
    )


def effect_to_dict(effect: Effect) -> dict[str, Any]:
    """``{"effect": name, "parameters": {...}}``, as a table stores an extension."""
    return {"effect": effect.name, "parameters": effect.parameters()}
