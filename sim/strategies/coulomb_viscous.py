"""``coulomb_viscous``: ``F = F_c sat(v / v_band) + b v``, the static friction
feedforward drives offer (a linear ramp through a small velocity band)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.runtime.observer import ForceModel
from gms_comp.tables.table import GmsTable
from sim.strategies.base import CompiledModel, StrategyInputs, compiled_step


@compiled_step
def coulomb_viscous_step(
    p: FloatArray, state: FloatArray, gms: object, position_m: float, velocity_m_s: float
) -> float:  # pragma: no cover
    """``params = [F_c, b, v_band]``: ``F_c sat(v / v_band) + b v``."""
    ramp = min(max(velocity_m_s / p[2], -1.0), 1.0)
    return p[0] * ramp + p[1] * velocity_m_s


@dataclass
class CoulombViscous:
    """Static feedforward: Coulomb level through a velocity band, plus viscous."""

    coulomb_N: float
    viscous_Ns_per_m: float
    velocity_band_m_s: float
    _compiled: CompiledModel = field(init=False, repr=False)

    def __post_init__(self) -> None:
        params = [self.coulomb_N, self.viscous_Ns_per_m, self.velocity_band_m_s]
        self._compiled = CompiledModel(coulomb_viscous_step, np.array(params))

    def compiled(self) -> CompiledModel:
        """The compiled step and its parameters."""
        return self._compiled

    def reset(self) -> None:
        """Stateless."""

    def step(self, position_m: float, velocity_m_s: float) -> float:
        """Force for the commanded velocity."""
        return self._compiled.force(position_m, velocity_m_s)


class CoulombViscousStrategy:
    """Coulomb + viscous, calibrated on the truth."""

    name = "coulomb_viscous"

    def source(self, inputs: StrategyInputs) -> GmsTable | ForceModel | None:
        """The calibrated model with the configured velocity band."""
        cal = inputs.calibration()
        return CoulombViscous(cal.coulomb_N, cal.viscous_Ns_per_m, inputs.velocity_band_m_s)
