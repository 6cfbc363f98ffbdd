"""The diagnosis policy of ``inertia``: m >= 0, for a friction force only (a drive force
holds the mass in its baseline)."""

from __future__ import annotations

from typing import ClassVar

from gms_comp.measured.policies.base import Policy
from gms_comp.runtime import effects as fx


class InertiaPolicy(Policy):
    """The acceleration's column, fitted non-negative."""

    effect: ClassVar[type[fx.Effect]] = fx.Inertia
    coefficient_lower: ClassVar[float] = 0.0
    basis_reads_gms: ClassVar[bool] = False
    force_kinds: ClassVar[tuple[str, ...]] = ("friction",)
    size_parameter: ClassVar[str] = "mass_kg"
    to_see_smaller: ClassVar[str] = "harder accelerations (shorter ramps between speeds)"
