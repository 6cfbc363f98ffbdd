"""Whether a change of the held-out residual is worth an effect: by a relative margin,
or by a smaller one that is significant against the residual's own spread."""

from __future__ import annotations

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.measured.diagnosis.config import SelectionConfig
from gms_comp.measured.diagnosis.design import rms


def significance(current: FloatArray, new: FloatArray, chunks: int) -> float:
    """z statistic of the drop in squared residual, its spread from contiguous chunks.

    With ``d = current - new`` (what the trial changes), the drop is
    ``sum(current**2 - new**2) = sum(2 new d + d**2)``; where the trial is right, ``new``
    is the noise and the drop's chance part is ``2 sum(new d)``, whose spread is taken
    over contiguous chunks (residuals are correlated in time, chunks much less so). Unlike
    a t test of the chunks' gains, this does not cap an effect that acts in a few chunks
    only (fast moves, break-aways) at the square root of their number."""
    n = min(chunks, current.size // 2)
    if n < 2:
        return 0.0
    change = current - new
    drop = float(np.sum(current**2 - new**2))
    cross = np.array([np.sum(c) for c in np.array_split(new * change, n)])
    spread = 2.0 * float(np.sqrt(np.sum(cross**2)))
    return drop / spread if spread > 0 else (np.inf if drop > 0 else 0.0)


def lowers(rules: SelectionConfig, current: FloatArray, new: FloatArray) -> bool:
    """Whether the held-out residual ``new`` is worth an effect against ``current``: its
    RMS lower by the margin, or by the small margin and significant."""
    rms0, rms1 = rms(current), rms(new)
    z = rules.significance_t
    return rms1 <= (1.0 - rules.margin) * rms0 or (
        rms1 <= (1.0 - rules.small_margin) * rms0
        and significance(current, new, rules.significance_chunks) >= z
    )


def lowers_locally(
    rules: SelectionConfig, current: FloatArray, new: FloatArray, noise_N: float
) -> bool:
    """Whether an effect that acts on few rows is worth keeping, judged there
    (``current``, ``new``: the residuals at those rows without and with it, every event
    by a fit that left it out): significant (``local_significance_t``), and lowering
    what those rows hold above the force's noise ``noise_N`` (the RMS with the noise's
    share taken out) by ``local_margin``. The RMS itself, noise included, could not show
    a gain that stands far out: dwell_time-240 of the independent generator (a 13 %
    break-away gain after the median standstill, noise 1.4 % of the level) dropped the
    RMS at its starts 6.5 % only (0.1489 -> 0.1392 N, noise 0.1323 N) with z 7.7; above
    the noise, 0.068 -> 0.043 N."""
    if current.size == 0:
        return False
    above0, above1 = (np.sqrt(max(rms(r) ** 2 - noise_N**2, 0.0)) for r in (current, new))
    return (
        above0 > 0.0
        and above1 <= (1.0 - rules.local_margin) * above0
        and significance(current, new, rules.significance_chunks) >= rules.local_significance_t
    )
