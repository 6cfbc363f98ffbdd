"""What a trace's motion cannot tell apart: caveats printed beside the causes.

- ``speed_direction``: where each direction holds one narrow band of speeds and the two
  differ, a force of the speed (viscous, stribeck) and one of the direction
  (direction_asymmetry, offset) are the same two numbers, one per band; only the ramps
  tell them apart, and the diagnosis names the one that fits best.
- ``near_tie``: as the first effect was kept, another lowered the held-out error nearly as
  much (motion can confound pairs no rule of the speeds lists).
- ``at_bound``: a kept effect's shape ended at the bound of its search (a Stribeck speed at
  half the top speed: the fall may go on above the trace's speeds).
- ``drive_force``: a friction force explained by a mass may be a drive's force.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.measured.diagnosis.config import CaveatConfig
from gms_comp.measured.policies import POLICIES, policy
from gms_comp.runtime import effects as fx
from gms_comp.runtime.effects.path import Context

# Speeds are binned by this many decades of log10 (a band: adjacent bins that each hold
# ``band_share`` of a direction's moving time).
BAND_BIN_DECADES = 0.1
# The effects a confound of speed and direction concerns.
SPEED_OR_DIRECTION = tuple(name for name, p in POLICIES.items() if p.speed_or_direction)


@dataclass(frozen=True)
class Caveat:
    """Effects a trace's motion cannot tell apart, and why, in words."""

    kind: str
    effects: tuple[str, ...]
    text: str

    def to_json(self) -> dict[str, Any]:
        """``kind``, ``effects`` and ``text``."""
        return {"kind": self.kind, "effects": list(self.effects), "text": self.text}


def speed_bands(speed_m_s: FloatArray, share: float) -> list[tuple[float, float, float]]:
    """The bands of speed a direction holds: (lowest, highest m/s, share of the time),
    from bins of ``BAND_BIN_DECADES`` that each hold ``share`` of ``speed_m_s``'s samples
    (all positive), adjacent bins merged."""
    if speed_m_s.size == 0:
        return []
    logs = np.log10(speed_m_s)
    first = np.floor(float(np.min(logs)) / BAND_BIN_DECADES)
    index = np.floor(logs / BAND_BIN_DECADES - first).astype(np.int64)
    counts = np.bincount(index)
    held = counts >= share * speed_m_s.size
    bands = []
    edges = np.flatnonzero(np.diff(np.concatenate(([0], held.astype(np.int8), [0]))))
    for lo, hi in zip(edges[::2], edges[1::2], strict=True):
        bands.append((
            float(10 ** ((first + lo) * BAND_BIN_DECADES)),
            float(10 ** ((first + hi) * BAND_BIN_DECADES)),
            float(np.sum(counts[lo:hi]) / speed_m_s.size),
        ))  # fmt: skip
    return bands


def speed_direction_confound(
    velocity_m_s: FloatArray, standstill_m_s: float, rules: CaveatConfig
) -> Caveat | None:
    """A caveat when each direction moves in one narrow band of speeds and the two bands
    differ (module docstring); None otherwise, or when the trace moves one way only."""
    moving = np.abs(velocity_m_s) > standstill_m_s
    forward = speed_bands(velocity_m_s[moving & (velocity_m_s > 0)], rules.band_share)
    back = speed_bands(-velocity_m_s[moving & (velocity_m_s < 0)], rules.band_share)
    if len(forward) != 1 or len(back) != 1:
        return None
    (f_lo, f_hi, _), (b_lo, b_hi, _) = forward[0], back[0]
    narrow = f_hi / f_lo <= rules.narrow_band and b_hi / b_lo <= rules.narrow_band
    if not narrow or (f_lo < b_hi and b_lo < f_hi):
        return None
    return Caveat(
        "speed_direction",
        SPEED_OR_DIRECTION,
        f"speed and direction go together on this trace: forward at {f_lo * 1e3:.3g}-"
        f"{f_hi * 1e3:.3g} mm/s only, back at {b_lo * 1e3:.3g}-{b_hi * 1e3:.3g} mm/s only, "
        f"so a force of the speed (viscous, stribeck) and one of the direction "
        f"(direction_asymmetry, offset) fit it alike; a run at the same speeds both ways "
        f"tells them apart",
    )


def near_tie(
    first: str, design_rms_N: float, trials: Sequence[tuple[str, float]], share: float
) -> Caveat | None:
    """A caveat when effects of the first round's admissible ``trials`` (name, held-out
    RMS) other than the ``first`` one named lowered the design's held-out RMS
    ``design_rms_N`` by ``share`` of the first one's drop or more; None otherwise, or
    when the first one named was not among them (the refit ranked another first)."""
    held = dict(trials)
    if first not in held or held[first] >= design_rms_N:
        return None
    drop = design_rms_N - held[first]
    near = sorted(
        ((h, name) for name, h in held.items()
         if name != first and design_rms_N - h >= share * drop),
    )  # fmt: skip
    if not near:
        return None
    others = ", ".join(f"{name} to {h:.4g} N" for h, name in near)
    return Caveat(
        "near_tie",
        (first, *(name for _, name in near)),
        f"the fit hardly tells {first} from {', '.join(name for _, name in near)} on this "
        f"trace: as the first effect was chosen, {first} took the held-out RMS from "
        f"{design_rms_N:.4g} N to {held[first]:.4g} N and {others}",
    )


def at_bound(
    effects: Sequence[fx.Effect], ctx: Context, presliding_m: float, factor: float
) -> Caveat | None:
    """A caveat naming the ``effects`` with a shape parameter at a bound of its search
    (within ``factor``; the bounds on the path ``ctx``); None when none is."""
    found = []
    for effect in effects:
        for key, (lo, hi) in policy(effect).shape_bounds(ctx, presliding_m).items():
            value = float(getattr(effect, key))
            if value >= hi / factor or value <= lo * factor:
                side = "upper" if value >= hi / factor else "lower"
                text = f"{effect.name}'s {key} at its {side} bound {value:.4g}"
                found.append((effect.name, text))
    if not found:
        return None
    return Caveat(
        "at_bound",
        tuple(dict.fromkeys(name for name, _ in found)),
        f"{'; '.join(text for _, text in found)}: the trace does not place it further "
        f"(a Stribeck speed at half the top speed: the fall may go on above the trace's "
        f"speeds, and its ratio is the fall within them), and the other parameters are "
        f"fitted with it held there",
    )


def drive_force(named: Sequence[str], force_kind: str) -> Caveat | None:
    """A caveat when the first effect named is one a drive force holds in its baseline
    (``Policy.force_kinds``: a mass) and the force was read as friction: it may be a
    drive force (a motor current times its force constant)."""
    if not named or force_kind != "friction" or "drive" in POLICIES[named[0]].force_kinds:
        return None
    return Caveat(
        "drive_force",
        (named[0],),
        f"the cause found is {named[0]}, which a drive force holds: if force_N is the "
        f"drive's force (a motor current times its force constant) rather than a friction "
        f"sensor's, this is the axis moving its own mass, not friction; diagnose it again "
        f"with --force-kind drive",
    )


def caveats(
    velocity_m_s: FloatArray, standstill_m_s: float, named: Sequence[str], rules: CaveatConfig,
    first_round: tuple[float, Sequence[tuple[str, float]]] = (0.0, ()),
    bounded: Caveat | None = None, force_kind: str = "friction",
) -> tuple[Caveat, ...]:  # fmt: skip
    """The caveats that concern any of the ``named`` effects; ``first_round``: the
    selection's first design held-out RMS and its admissible trials (:func:`near_tie`);
    ``bounded``: :func:`at_bound`'s; ``force_kind``: what the force was read as
    (:func:`drive_force`)."""
    found = [
        speed_direction_confound(velocity_m_s, standstill_m_s, rules), bounded,
        drive_force(named, force_kind),
    ]  # fmt: skip
    if named:
        found.append(near_tie(named[0], *first_round, rules.near_tie))
    return tuple(c for c in found if c is not None and set(c.effects) & set(named))
