"""``none``: no feedforward."""

from __future__ import annotations

from gms_comp.observer import ForceModel
from gms_comp.table import GmsTable

from .base import StrategyInputs


class NoFeedforward:
    """The uncompensated axis."""

    name = "none"

    def source(self, inputs: StrategyInputs) -> GmsTable | ForceModel | None:
        """No model."""
        return None
