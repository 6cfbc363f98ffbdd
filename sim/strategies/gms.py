"""``gms``: the GMS table (its physical extensions applied by the observer)."""

from __future__ import annotations

from gms_comp import gms as gms_kernel
from gms_comp.arrays import FloatArray
from gms_comp.gms import GmsStream
from gms_comp.runtime.observer import ForceModel
from gms_comp.tables.table import GmsTable
from sim.strategies.base import NO_ARRAY, CompiledModel, StrategyInputs, compiled_step


@compiled_step
def gms_step(
    p: FloatArray, state: FloatArray, gms: object, position_m: float, velocity_m_s: float
) -> float:  # pragma: no cover
    """The GMS stream's own step (:func:`gms_comp.gms.stream_step`)."""
    return gms_kernel.stream_step(gms, position_m, velocity_m_s)


def compiled_gms(stream: GmsStream) -> CompiledModel:
    """The compiled form of a plain GMS stream (the runtime's model of a table)."""
    return CompiledModel(gms_step, NO_ARRAY, NO_ARRAY, stream.kernel)


class GmsStrategy:
    """The table of the scenario."""

    name = "gms"

    def source(self, inputs: StrategyInputs) -> GmsTable | ForceModel | None:
        """The GMS table."""
        return inputs.table()
