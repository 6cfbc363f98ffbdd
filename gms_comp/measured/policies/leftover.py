"""What a diagnosis's design leaves unexplained, for an effect's grid to search
(:class:`Leftover`).

An effect whose grid is found from the residual (a ripple's wavelengths) is best scanned
for what it would add to the design, not for what it shares with the residual: the GMS
elements absorb part of a ripple, and the residual's own spectrum then peaks elsewhere
(independent pair_position_ripple_inertia-205: a 4.88 mm ripple, the residual's
projection strongest at 5.58 mm; scored with the design, 4.865 mm). The scan reads a
sample of the training rows in motion, in contiguous blocks (so that short periods are
not aliased), against an orthonormal basis of the design on them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg

from gms_comp.arrays import BoolArray, FloatArray, IntArray

# The scan reads at most about this many rows, in blocks of BLOCK_ROWS consecutive ones.
SCAN_ROWS = 8000
BLOCK_ROWS = 32
# Directions of the (column-scaled) design below this share of its largest singular
# value are not part of its basis.
RANK_RCOND = 1e-10


@dataclass(frozen=True)
class Leftover:
    """The residual on ``rows`` of the path and an orthonormal basis of the design there.

    Parameters
    ----------
    residual_N
        The residual at ``rows``.
    rows
        The rows of the path read (training rows in motion, a sample of them).
    design
        Orthonormal columns spanning the design at ``rows`` (``rows.size`` x m; m may be 0).
    """

    residual_N: FloatArray
    rows: IntArray
    design: FloatArray

    @staticmethod
    def of(residual_N: FloatArray, read: BoolArray, design: FloatArray | None = None) -> Leftover:
        """The leftover of a design (columns along the whole path; None: no design) with
        the residual ``residual_N`` (along the whole path), read at a sample of the rows
        ``read`` (``SCAN_ROWS`` in blocks of ``BLOCK_ROWS``)."""
        rows = sample_rows(read)
        basis = np.zeros((rows.size, 0))
        if design is not None and design.shape[1] > 0 and rows.size > 0:
            # each column scaled to unit norm (element columns differ in size by orders),
            # a zero or duplicated one adding no direction
            values = design[rows]
            norm = np.linalg.norm(values, axis=0)
            values = values[:, norm > 0.0] / norm[norm > 0.0]
            if values.shape[1]:
                basis = linalg.orth(values, rcond=RANK_RCOND)
        return Leftover(np.asarray(residual_N, dtype=np.float64)[rows], rows, basis)

    @staticmethod
    def empty() -> Leftover:
        """No rows read (for an effect whose grid does not depend on the residual)."""
        return Leftover(np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros((0, 0)))

    def orthogonal(self, columns: FloatArray) -> FloatArray:
        """``columns`` (at ``rows``) less their projection on the design."""
        if self.design.shape[1] == 0:
            return columns
        return columns - self.design @ (self.design.T @ columns)

    def pair_gains(self, first: FloatArray, second: FloatArray) -> FloatArray:
        """For each pair of columns ``first[:, i]``, ``second[:, i]`` (at ``rows``): how
        much adding the pair to the design lowers the squared residual on ``rows`` (an
        unbounded least-squares fit)."""
        a, b = self.orthogonal(first), self.orthogonal(second)
        r = self.residual_N
        saa, sbb, sab = np.sum(a * a, axis=0), np.sum(b * b, axis=0), np.sum(a * b, axis=0)
        ra, rb = r @ a, r @ b
        det = saa * sbb - sab * sab
        tiny = 1e-12 * np.maximum(saa * sbb, np.finfo(float).tiny)
        gain = (sbb * ra * ra - 2.0 * sab * ra * rb + saa * rb * rb) / np.maximum(det, tiny)
        return np.where(det > tiny, gain, 0.0)


def sample_rows(read: BoolArray) -> IntArray:
    """About ``SCAN_ROWS`` of the rows ``read``, every k-th block of ``BLOCK_ROWS``
    consecutive ones (all of them where there are fewer)."""
    rows = np.flatnonzero(read)
    every = max(1, -(-rows.size // SCAN_ROWS))
    return rows[(np.arange(rows.size) // BLOCK_ROWS) % every == 0]
