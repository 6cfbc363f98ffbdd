"""``lugre``: LuGre feedforward (Canudas de Wit et al. 1995) without Stribeck peak,
``F = sigma0 z + sigma2 v``, bristle update in displacement form. LuGre's ``sigma1``
(micro-damping) has no counterpart in the ball model and is 0."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.runtime.observer import ForceModel
from gms_comp.tables.table import GmsTable
from sim.strategies.base import CompiledModel, StrategyInputs, compiled_step


@compiled_step
def lugre_step(
    p: FloatArray, state: FloatArray, gms: object, position_m: float, velocity_m_s: float
) -> float:  # pragma: no cover
    """``params = [F_c, sigma0, b]``, ``state = [z, last position]`` (NaN: none yet):
    ``dz/dx = 1 - sigma0 z sgn(dx) / F_c`` solved exactly over the step."""
    dx = 0.0 if math.isnan(state[1]) else position_m - state[1]
    state[1] = position_m
    if dx != 0.0:
        z_ss = math.copysign(p[0] / p[1], dx)
        state[0] = z_ss + (state[0] - z_ss) * math.exp(-p[1] * abs(dx) / p[0])
    return p[1] * state[0] + p[2] * velocity_m_s


@dataclass
class LuGre:
    """LuGre bristle model without a Stribeck peak, stepped by displacement.

    ``dz/dx = 1 - sigma0 z sgn(dx) / F_c`` is solved exactly over each step, so the
    update is stable for any step length (:func:`lugre_step`).
    """

    coulomb_N: float
    stiffness_N_per_m: float
    viscous_Ns_per_m: float
    _compiled: CompiledModel = field(init=False, repr=False)

    def __post_init__(self) -> None:
        params = [self.coulomb_N, self.stiffness_N_per_m, self.viscous_Ns_per_m]
        self._compiled = CompiledModel(lugre_step, np.array(params), np.zeros(2))
        self.reset()

    def compiled(self) -> CompiledModel:
        """The compiled step, its parameters and bristle state."""
        return self._compiled

    def reset(self) -> None:
        """Undeflected bristles; the next sample sets the reference position."""
        self._compiled.state[:] = [0.0, math.nan]

    def step(self, position_m: float, velocity_m_s: float) -> float:
        """Advance the bristle to ``position_m`` and return the force."""
        return self._compiled.force(position_m, velocity_m_s)


class LuGreStrategy:
    """LuGre, calibrated on the truth."""

    name = "lugre"

    def source(self, inputs: StrategyInputs) -> GmsTable | ForceModel | None:
        """The calibrated LuGre model."""
        cal = inputs.calibration()
        return LuGre(cal.coulomb_N, cal.lugre_stiffness_N_per_m, cal.viscous_Ns_per_m)
