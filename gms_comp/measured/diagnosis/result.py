"""Stage 6b: the diagnosis record, its verdict and its JSON (the spec's keys)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from gms_comp.arrays import FloatArray
from gms_comp.gms import GmsParams
from gms_comp.measured.diagnosis.coverage import Caveat
from gms_comp.measured.diagnosis.detection import Limit
from gms_comp.measured.diagnosis.intervals import Intervals
from gms_comp.measured.diagnosis.refit import Ranked
from gms_comp.measured.diagnosis.structure import Structure
from gms_comp.measured.policies import POLICIES
from gms_comp.runtime import effects as fx


@dataclass(frozen=True)
class Diagnosis:
    """Result of :func:`~gms_comp.measured.diagnosis.run.diagnose` (:meth:`to_json`: the
    spec's keys): ``effect`` the first kept effect's name, ``none``, or ``unknown`` (the
    residual still has structure; ``ranked`` then holds the partial candidates)."""

    effect: str
    ranked: tuple[Ranked, ...]
    baseline_rms_N: float
    extended_rms_N: float
    baseline: dict[str, Any]
    phases: dict[str, dict[str, float]]
    base_gms: GmsParams  # the baseline's GMS, without the effects' refit
    gms: GmsParams
    extensions: tuple[fx.Effect, ...]
    structure: Structure
    tried: list[dict[str, Any]]  # the best trial of every effect in the last round
    series: dict[str, FloatArray]  # for the report's plots
    seconds: float
    # each ranked effect's figures along the trace (:meth:`~.effects.Effect.in_context`)
    in_context: tuple[dict[str, float], ...]
    # how the extensions saw the path (rest, reversals): travels with them into the table
    extension_context: dict[str, float] = field(default_factory=dict)
    # what the trace's motion cannot tell apart among the ranked effects (:mod:`.coverage`)
    caveats: tuple[Caveat, ...] = ()
    # each ranked effect's 95 % intervals (:mod:`.intervals`)
    intervals: tuple[Intervals, ...] = ()
    # each catalogue effect's detection limit on this trace (:mod:`.detection`)
    limits: dict[str, Limit] = field(default_factory=dict)

    @property
    def noise_rms_N(self) -> float:
        """The noise estimated from the extended model's held-out residual."""
        return self.structure.noise_rms_N

    @property
    def gain(self) -> float:
        """1 - extended / baseline held-out RMS."""
        return 1.0 - self.extended_rms_N / self.baseline_rms_N if self.baseline_rms_N else 0.0

    def to_json(self) -> dict[str, Any]:
        """The spec's keys (and the structure, the candidates tried, the run time)."""
        named = self.effect not in ("none", "unknown")
        return {
            "effect": self.effect,
            "effects": [
                {
                    "effect": c.effect.name,
                    "parameters": c.effect.parameters(),
                    "heldout_rms_N": c.heldout_rms_N,
                    "intervals_95": sure.to_json(),
                    "interval_at_bound": list(sure.at_bound),
                }
                | ({"in_context": figures} if figures else {})
                for c, figures, sure in zip(
                    self.ranked, self.in_context, self.intervals, strict=True
                )
            ],
            "parameters": self.ranked[0].effect.parameters() if named else {},
            "baseline_rms_N": self.baseline_rms_N,
            "extended_rms_N": self.extended_rms_N,
            "extended_slip_level": float(self.gms.slip_level),
            "extended_limit_follows_level": self.gms.limit_follows_level,
            "extended_transition_velocity_m_s": float(self.gms.transition_velocity_m_s),
            "extended_transition_exponent": float(self.gms.transition_exponent),
            "extended_transition_tail": (
                None if math.isinf(tail := self.gms.transition_tail) else float(tail)
            ),
            "gain": self.gain,
            "noise_rms_N": self.noise_rms_N,
            "baseline": self.baseline,
            "phases": self.phases,
            "structure": self.structure.to_json(),
            "caveats": [c.to_json() for c in self.caveats],
            "detection_limits": {name: limit.figures for name, limit in self.limits.items()},
            "detection_limits_range": {name: limit.span for name, limit in self.limits.items()},
            "to_see_smaller": {name: POLICIES[name].to_see_smaller for name in self.limits},
            "candidates_tried": self.tried,
            "seconds": self.seconds,
        }


def verdict(ranked: tuple[Ranked, ...], structure: Structure) -> str:
    """The named cause: ``unknown`` when structure is left, else the first kept effect,
    else ``none``."""
    if structure.structured:
        return "unknown"
    return ranked[0].effect.name if ranked else "none"


# Units of parameter names by their suffix (longest first), for people.
_UNITS = (
    ("_Ns_per_m", "N s/m"), ("_m_per_s", "m/s"), ("_m_s", "m/s"), ("_Hz", "Hz"), ("_kg", "kg"),
    ("_rad", "rad"), ("_N", "N"), ("_s", "s"), ("_m", "m"),
)  # fmt: skip


def parameter_text(name: str, value: float) -> str:
    """``name = value unit`` with the unit read from the name's suffix."""
    for suffix, unit in _UNITS:
        if name.endswith(suffix):
            return f"{name[: -len(suffix)]} = {value:.4g} {unit}"
    return f"{name} = {value:.4g}"
