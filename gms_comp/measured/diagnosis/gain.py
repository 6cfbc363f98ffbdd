"""Whether a change of the held-out residual is worth an effect: by a relative margin,
or by a smaller one that is significant against the residual's own spread."""

from __future__ import annotations

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.measured.diagnosis.config import DiagnosisConfig
from gms_comp.measured.diagnosis.design import rms

# Contiguous chunks of held-out samples for the significance of an improvement.
SIGNIFICANCE_CHUNKS = 50


def significance(current: FloatArray, new: FloatArray) -> float:
    """z statistic of the drop in squared residual, its spread from contiguous chunks.

    With ``d = current - new`` (what the trial changes), the drop is
    ``sum(current**2 - new**2) = sum(2 new d + d**2)``; where the trial is right, ``new``
    is the noise and the drop's chance part is ``2 sum(new d)``, whose spread is taken
    over contiguous chunks (residuals are correlated in time, chunks much less so). Unlike
    a t test of the chunks' gains, this does not cap an effect that acts in a few chunks
    only (fast moves, break-aways) at the square root of their number."""
    n = min(SIGNIFICANCE_CHUNKS, current.size // 2)
    if n < 2:
        return 0.0
    change = current - new
    drop = float(np.sum(current**2 - new**2))
    cross = np.array([np.sum(c) for c in np.array_split(new * change, n)])
    spread = 2.0 * float(np.sqrt(np.sum(cross**2)))
    return drop / spread if spread > 0 else (np.inf if drop > 0 else 0.0)


def lowers(cfg: DiagnosisConfig, current: FloatArray, new: FloatArray) -> bool:
    """Whether the held-out residual ``new`` is worth an effect against ``current``: its
    RMS lower by the margin, or by the small margin and significant."""
    rms0, rms1 = rms(current), rms(new)
    return rms1 <= (1.0 - cfg.margin) * rms0 or (
        rms1 <= (1.0 - cfg.small_margin) * rms0 and significance(current, new) >= cfg.significance_t
    )
