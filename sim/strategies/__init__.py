"""The compensation strategies compared in a scenario: one module each, registered here.

Adding a strategy: a new module with a class that has a ``name`` and a ``source``
method (:class:`sim.strategies.base.Strategy`; a model with a compiled step offers
``compiled()``), and one line in :data:`REGISTRY`.
"""

from __future__ import annotations

from gms_comp.gms import GmsStream
from gms_comp.runtime.observer import ForceModel
from sim.strategies.base import Calibration, CompiledModel, Strategy, StrategyInputs, calibrate
from sim.strategies.coulomb_viscous import CoulombViscous, CoulombViscousStrategy
from sim.strategies.gms import GmsStrategy, compiled_gms
from sim.strategies.lugre import LuGre, LuGreStrategy
from sim.strategies.none import NoFeedforward

REGISTRY: dict[str, Strategy] = {
    s.name: s
    for s in (
        NoFeedforward(),
        CoulombViscousStrategy(),
        LuGreStrategy(),
        GmsStrategy(),
    )
}
STRATEGIES = tuple(REGISTRY)


def compiled_form(model: ForceModel) -> CompiledModel | None:
    """The compiled step of a feedforward model, None if it has none (a table with
    physical extensions, any other Python model)."""
    if isinstance(model, GmsStream):
        return compiled_gms(model)
    compiled = getattr(model, "compiled", None)
    return compiled() if callable(compiled) else None


__all__ = [
    "REGISTRY",
    "STRATEGIES",
    "Calibration",
    "CompiledModel",
    "CoulombViscous",
    "LuGre",
    "Strategy",
    "StrategyInputs",
    "calibrate",
    "compiled_form",
]
