"""The interface every feedforward strategy implements, and their fair calibration.

A strategy (one module in this package, registered in one line of its
``__init__``) names itself and builds the compensator's model for a scenario from
:class:`StrategyInputs`: the GMS table, the calibration of the static baselines, the
velocity band. The model is a GMS table, any :class:`gms_comp.runtime.observer.ForceModel`, or
``None`` for no feedforward. A model that offers ``compiled() -> CompiledModel`` runs
inside the closed loop's one compiled call; its step is a numba function of the one
signature :data:`STEP_SIGNATURE`, passed to the loop as a first-class function (no kind
tags to dispatch on).

Coulomb-viscous and LuGre are calibrated from the same friction truth the GMS table is
reduced from (:func:`calibrate`): ``F_c`` and ``b`` from the steady sliding force at two
speeds, ``sigma0`` by least squares on the truth's virgin (presliding) curve.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numba
import numpy as np
from numba import types
from scipy.optimize import minimize_scalar

from gms_comp.arrays import FloatArray
from gms_comp.gms import GmsParams, GmsStream
from gms_comp.runtime.observer import ForceModel
from gms_comp.tables.table import GmsTable

NO_GMS = GmsStream(GmsParams(np.ones(1), np.zeros(1))).kernel
NO_ARRAY = np.zeros(1)

# step(params, state, gms kernel, position m, velocity m/s) -> resisting force N
STEP_SIGNATURE = types.float64(
    types.float64[::1], types.float64[::1], numba.typeof(NO_GMS), types.float64, types.float64
)


def compiled_step(function: Callable[..., float]) -> Any:
    """Compile a strategy's step with :data:`STEP_SIGNATURE` (cached on disk)."""
    return numba.njit(STEP_SIGNATURE, cache=True)(function)


@dataclass(frozen=True)
class CompiledModel:
    """A model's compiled step and the arrays it works on (its own, stepped in place)."""

    step: Any
    params: FloatArray
    state: FloatArray = field(default_factory=lambda: np.zeros(1))
    gms: Any = NO_GMS

    def force(self, position_m: float, velocity_m_s: float) -> float:
        """One step from Python (the same compiled function the loop calls)."""
        return float(self.step(self.params, self.state, self.gms, position_m, velocity_m_s))


@dataclass(frozen=True)
class Calibration:
    """What the baselines learn from the truth (the whole axis's friction)."""

    coulomb_N: float
    viscous_Ns_per_m: float
    lugre_stiffness_N_per_m: float


@dataclass(frozen=True)
class StrategyInputs:
    """What a strategy may build its model from (computed only when asked for)."""

    calibration: Callable[[], Calibration]
    table: Callable[[], GmsTable]
    velocity_band_m_s: float


class Strategy(Protocol):
    """A feedforward strategy: its name and its model for a scenario."""

    name: str

    def source(self, inputs: StrategyInputs) -> GmsTable | ForceModel | None:
        """The compensator's model (None: no feedforward)."""
        ...


def _sweep(truth: ForceModel, travel_m: float, velocity_m_s: float, samples: int) -> FloatArray:
    """Force of ``truth`` along a constant-velocity move from rest."""
    truth.reset()
    x = np.linspace(0.0, travel_m, samples)
    return np.array([truth.step(float(p), velocity_m_s) for p in x])


def calibrate(
    truth: ForceModel, travel_m: float, velocities_m_s: tuple[float, float], samples: int = 2000
) -> Calibration:
    """Calibrate Coulomb-viscous and LuGre from a fresh ``truth`` (it is reset)."""
    curves = [_sweep(truth, travel_m, v, samples) for v in velocities_m_s]
    (v1, v2), (f1, f2) = velocities_m_s, (curves[0][-1], curves[1][-1])
    viscous = max(0.0, (f2 - f1) / (v2 - v1))
    coulomb = f1 - viscous * v1
    x = np.linspace(0.0, travel_m, samples)
    virgin = curves[0] - viscous * v1

    def misfit(log_k: float) -> float:
        model = coulomb * (1.0 - np.exp(-(10.0**log_k) * x / coulomb))
        return float(np.sum((model - virgin) ** 2))

    # Bracket: presliding over between a thousandth and the whole of the travel.
    low, high = math.log10(coulomb / travel_m), math.log10(1e3 * coulomb / travel_m)
    best = minimize_scalar(misfit, bounds=(low, high), method="bounded")
    return Calibration(float(coulomb), float(viscous), float(10.0**best.x))
