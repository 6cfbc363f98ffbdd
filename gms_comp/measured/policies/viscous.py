"""The diagnosis policy of ``viscous``: c >= 0 (viscous friction dissipates)."""

from __future__ import annotations

from typing import ClassVar

from gms_comp.measured.policies.base import Policy
from gms_comp.runtime import effects as fx


class ViscousPolicy(Policy):
    """A slope on the velocity, fitted non-negative."""

    effect: ClassVar[type[fx.Effect]] = fx.Viscous
    coefficient_lower: ClassVar[float] = 0.0
    basis_reads_gms: ClassVar[bool] = False
    speed_or_direction: ClassVar[bool] = True
    size_parameter: ClassVar[str] = "c_Ns_per_m"
    to_see_smaller: ClassVar[str] = "strokes at higher steady speeds, both ways"
