"""The compensation strategies compared in a scenario, and their fair calibration.

- ``none``: no feedforward.
- ``coulomb_viscous``: ``F = F_c sat(v / v_band) + b v``, the static friction
  feedforward drives offer (a linear ramp through a small velocity band).
- ``lugre``: LuGre feedforward (Canudas de Wit et al. 1995) without Stribeck
  peak, ``F = sigma0 z + sigma2 v``, bristle update in displacement form.
- ``gms``: the GMS table.

Coulomb-viscous and LuGre are calibrated from the same friction truth the GMS
table is reduced from: ``F_c`` and ``b`` from the steady sliding force at two
speeds, ``sigma0`` by least squares on the truth's virgin (presliding) curve.
LuGre's ``sigma1`` (micro-damping) has no counterpart in the ball model and is 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from gms_comp.observer import ForceModel

from .kernels import COULOMB_VISCOUS, LUGRE, model_force, model_pack
from .plant import Friction

STRATEGIES = ("none", "coulomb_viscous", "lugre", "gms")


@dataclass
class CoulombViscous:
    """Static feedforward: Coulomb level through a velocity band, plus viscous."""

    coulomb_N: float
    viscous_Ns_per_m: float
    velocity_band_m_s: float

    def __post_init__(self) -> None:
        params = [self.coulomb_N, self.viscous_Ns_per_m, self.velocity_band_m_s]
        self.pack = model_pack(COULOMB_VISCOUS, np.array(params))

    def reset(self) -> None:
        """Stateless."""

    def step(self, position_m: float, velocity_m_s: float) -> float:
        """Force for the commanded velocity."""
        return float(model_force(self.pack, position_m, velocity_m_s))


@dataclass
class LuGre:
    """LuGre bristle model without a Stribeck peak, stepped by displacement.

    ``dz/dx = 1 - sigma0 z sgn(dx) / F_c`` is solved exactly over each step, so the
    update is stable for any step length (:func:`sim.kernels.model_force`).
    """

    coulomb_N: float
    stiffness_N_per_m: float
    viscous_Ns_per_m: float

    def __post_init__(self) -> None:
        params = [self.coulomb_N, self.stiffness_N_per_m, self.viscous_Ns_per_m]
        self.pack = model_pack(LUGRE, np.array(params), np.zeros(2))
        self.reset()

    def reset(self) -> None:
        """Undeflected bristles; the next sample sets the reference position."""
        self.pack[2][:] = [0.0, math.nan]

    def step(self, position_m: float, velocity_m_s: float) -> float:
        """Advance the bristle to ``position_m`` and return the force."""
        return float(model_force(self.pack, position_m, velocity_m_s))


@dataclass(frozen=True)
class Calibration:
    """What the baselines learn from the truth (one friction source, unscaled)."""

    coulomb_N: float
    viscous_Ns_per_m: float
    lugre_stiffness_N_per_m: float


def _sweep(truth: Friction, travel_m: float, velocity_m_s: float, samples: int) -> np.ndarray:
    """Force of ``truth`` along a constant-velocity move from rest."""
    truth.reset()
    x = np.linspace(0.0, travel_m, samples)
    return np.array([truth.step(float(p), velocity_m_s) for p in x])


def calibrate(
    truth: Friction, travel_m: float, velocities_m_s: tuple[float, float], samples: int = 2000
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


def baseline_model(name: str, cal: Calibration, velocity_band_m_s: float) -> ForceModel:
    """The ``coulomb_viscous`` or ``lugre`` force model of a calibration."""
    if name == "coulomb_viscous":
        return CoulombViscous(cal.coulomb_N, cal.viscous_Ns_per_m, velocity_band_m_s)
    if name == "lugre":
        return LuGre(cal.coulomb_N, cal.lugre_stiffness_N_per_m, cal.viscous_Ns_per_m)
    raise ValueError(f"no baseline model named {name!r}")
