"""What a trace's motion cannot tell apart: caveats printed beside the causes.

A force that depends on the speed (viscous, a Stribeck fall) and one that depends on the
direction (a direction asymmetry, an offset) are different columns of the design only
where the trace moves at the same speeds both ways, or at several speeds one way. Where
each direction holds one narrow band of speeds and the two bands differ, every force of
the speed and the direction is two numbers, one per band: the baseline's sliding level
and any one of those effects fit it alike, and only the speed-up and slow-down ramps
tell them apart. The diagnosis still names the effect that fits best; the caveat says
that the trace could not have told it from the others.

Measured on the independent generator's seeds 101-130 (tests/indepgen.py): seed 119
moves forward at 6.3-7.9 mm/s only and back at 1.0-1.6 mm/s only, and its hidden Stribeck
fall was named ``direction_asymmetry`` (both fit the held-out rows within 3 %). On
every other seed, and on EMPS, some direction holds two bands or a band wider than
``NARROW_BAND``, or the bands overlap.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gms_comp.arrays import FloatArray

# Speeds are binned by BAND_BIN_DECADES of log10; bins that hold at least BAND_SHARE of
# a direction's moving time are its bands (adjacent held bins: one band).
BAND_BIN_DECADES = 0.1
BAND_SHARE = 0.02
# A band narrower than this factor (top / bottom speed) is one speed for a fit: on seed
# 119, 6.3-7.9 mm/s (1.26) and 1.0-1.6 mm/s (1.58).
NARROW_BAND = 2.0
# The effects a confound of speed and direction concerns.
SPEED_OR_DIRECTION = ("viscous", "stribeck", "direction_asymmetry", "offset")


@dataclass(frozen=True)
class Caveat:
    """Effects a trace's motion cannot tell apart, and why, in words."""

    kind: str
    effects: tuple[str, ...]
    text: str

    def to_json(self) -> dict[str, Any]:
        """``kind``, ``effects`` and ``text``."""
        return {"kind": self.kind, "effects": list(self.effects), "text": self.text}


def speed_bands(speed_m_s: FloatArray) -> list[tuple[float, float, float]]:
    """The bands of speed a direction holds: (lowest, highest m/s, share of the time),
    from bins of ``BAND_BIN_DECADES`` that each hold ``BAND_SHARE`` of ``speed_m_s``'s
    samples (all positive), adjacent bins merged."""
    if speed_m_s.size == 0:
        return []
    logs = np.log10(speed_m_s)
    first = np.floor(float(np.min(logs)) / BAND_BIN_DECADES)
    index = np.floor(logs / BAND_BIN_DECADES - first).astype(np.int64)
    counts = np.bincount(index)
    held = counts >= BAND_SHARE * speed_m_s.size
    bands = []
    edges = np.flatnonzero(np.diff(np.concatenate(([0], held.astype(np.int8), [0]))))
    for lo, hi in zip(edges[::2], edges[1::2], strict=True):
        bands.append((
            float(10 ** ((first + lo) * BAND_BIN_DECADES)),
            float(10 ** ((first + hi) * BAND_BIN_DECADES)),
            float(np.sum(counts[lo:hi]) / speed_m_s.size),
        ))  # fmt: skip
    return bands


def speed_direction_confound(velocity_m_s: FloatArray, standstill_m_s: float) -> Caveat | None:
    """A caveat when each direction moves in one narrow band of speeds and the two bands
    differ (module docstring); None otherwise, or when the trace moves one way only."""
    moving = np.abs(velocity_m_s) > standstill_m_s
    forward = speed_bands(velocity_m_s[moving & (velocity_m_s > 0)])
    back = speed_bands(-velocity_m_s[moving & (velocity_m_s < 0)])
    if len(forward) != 1 or len(back) != 1:
        return None
    (f_lo, f_hi, _), (b_lo, b_hi, _) = forward[0], back[0]
    narrow = f_hi / f_lo <= NARROW_BAND and b_hi / b_lo <= NARROW_BAND
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


def caveats(
    velocity_m_s: FloatArray, standstill_m_s: float, named: Sequence[str]
) -> tuple[Caveat, ...]:
    """The caveats that concern any of the ``named`` effects."""
    found = [speed_direction_confound(velocity_m_s, standstill_m_s)]
    return tuple(c for c in found if c is not None and set(c.effects) & set(named))
