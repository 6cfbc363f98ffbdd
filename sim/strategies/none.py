"""``none``: no feedforward."""

from __future__ import annotations

from gms_comp.runtime.observer import ForceModel
from gms_comp.tables.table import GmsTable
from sim.strategies.base import StrategyInputs


class NoFeedforward:
    """The uncompensated axis."""

    name = "none"

    def source(self, inputs: StrategyInputs) -> GmsTable | ForceModel | None:
        """No model."""
        return None
