"""The diagnosis policy of ``offset``: a constant force of either sign."""

from __future__ import annotations

from typing import ClassVar

from gms_comp.measured.policies.base import Policy
from gms_comp.runtime import effects as fx


class OffsetPolicy(Policy):
    """A column of ones."""

    effect: ClassVar[type[fx.Effect]] = fx.Offset
    basis_reads_gms: ClassVar[bool] = False
    speed_or_direction: ClassVar[bool] = True
    size_parameter: ClassVar[str] = "offset_N"
    to_see_smaller: ClassVar[str] = "as much travel forward as back, at the same speeds"
