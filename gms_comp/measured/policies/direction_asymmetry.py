"""The diagnosis policy of ``direction_asymmetry``: judged where the motion tells it from
a force of the speed."""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from gms_comp.arrays import BoolArray
from gms_comp.measured.policies.base import Policy
from gms_comp.runtime import effects as fx


class DirectionAsymmetryPolicy(Policy):
    """Half the speed, either sign."""

    effect: ClassVar[type[fx.Effect]] = fx.DirectionAsymmetry
    basis_reads_gms: ClassVar[bool] = False
    speed_or_direction: ClassVar[bool] = True
    size_parameter: ClassVar[str] = "c_diff_Ns_per_m"
    to_see_smaller: ClassVar[str] = "the same speeds both ways, several of them"

    @classmethod
    def told_apart(cls, ctxs: Sequence[fx.Context]) -> list[BoolArray]:
        """The moving rows at speeds the parts reach both ways: where one direction alone
        moves at a speed, half its speed is also a level that falls or rises with the
        speed there (a one-way fast move took a Stribeck fall as well as Stribeck did).
        None on a trace that moves one way only."""
        moving = [(c.velocity_m_s, c.moving != 0.0) for c in ctxs]
        both = min(
            max(float(np.max(sign * v[m], initial=0.0)) for v, m in moving) for sign in (1.0, -1.0)
        )
        return [m & (np.abs(v) <= both) & (both > 0.0) for v, m in moving]
