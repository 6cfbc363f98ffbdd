"""Least-squares machinery of the diagnosis: design columns, bounded solves, Gram scoring.

Every model the diagnosis compares is linear in its coefficients once its shape
parameters are fixed: the GMS limits W_i (on a grid of break-away displacements), the
mass for a drive force, and the catalogue effects' coefficients are columns of one
design. Candidates are scored without refactorising the whole design for every trial:
:class:`GramDesign` keeps the training Gram matrix of the current design, and a trial's
extra columns only add their cross products (n x m x q operations for q new columns
instead of n x (m + q)^2), then a bounded solve in m + q unknowns.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import linalg, optimize

from gms_comp.arrays import BoolArray, FloatArray, IntArray

# Ridge (relative to the unit diagonal of the scaled Gram matrix) that keeps an empty or
# duplicated column from making the solve singular; its coefficient then stays near 0.
RIDGE = 1e-10
# Trials scored together read the design once (:meth:`GramDesign.trials`): at most this
# many extra columns at a time (a 131 000-row batch of them: 64 MB).
BATCH_COLUMNS = 64


def rms(x: FloatArray) -> float:
    """Root mean square (0 for an empty array)."""
    return float(np.sqrt(np.mean(x * x))) if x.size else 0.0


@dataclass(frozen=True)
class Columns:
    """Design columns of one model part with the lower bounds of their coefficients."""

    values: FloatArray  # (n, k)
    lower: FloatArray  # (k,)

    @staticmethod
    def join(blocks: Sequence[Columns]) -> Columns:
        """The blocks side by side, stacked once (joined pairwise, the tall matrix was
        copied k - 1 times)."""
        if len(blocks) == 1:
            return blocks[0]
        return Columns(
            np.column_stack([b.values for b in blocks]), np.concatenate([b.lower for b in blocks])
        )


def solve(a: FloatArray, y: FloatArray, lower: FloatArray) -> FloatArray:
    """min ||a c - y|| with c >= lower (use -inf for free coefficients)."""
    return solve_gram(a.T @ a, a.T @ y, lower)


def solve_gram(gram: FloatArray, rhs: FloatArray, lower: FloatArray) -> FloatArray:
    """min c'Gc - 2 c'g with c >= lower, from the Gram matrix G and g = A'y.

    Columns are scaled to unit norm first (the bounds with them), so that element
    columns of very different sizes share one tolerance. The free coefficients (lower
    -inf) are eliminated (Schur complement), the bounded ones shifted to their bounds,
    and the rest is a non-negative least-squares problem on the Cholesky factor, solved
    by scipy's compiled Lawson-Hanson :func:`scipy.optimize.nnls` (a diagnosis solves
    thousands)."""
    d = np.sqrt(np.maximum(np.diag(gram), 0.0))
    scale = np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), 1.0)
    g = gram * np.outer(scale, scale) + RIDGE * np.eye(scale.size)
    b = rhs * scale
    free = np.isneginf(lower)
    if free.all():
        c = linalg.cho_solve(linalg.cho_factor(g, check_finite=False), b, check_finite=False)
        return np.asarray(c * scale, dtype=np.float64)
    bounded = ~free
    g_bb, b_b = g[np.ix_(bounded, bounded)], b[bounded]
    if free.any():
        g_fb = g[np.ix_(free, bounded)]
        factor = linalg.cho_factor(g[np.ix_(free, free)], check_finite=False)
        w = linalg.cho_solve(factor, np.column_stack([g_fb, b[free]]), check_finite=False)
        g_bb = g_bb - g_fb.T @ w[:, :-1]
        b_b = b_b - g_fb.T @ w[:, -1]
    low = lower[bounded] / scale[bounded]
    c = np.empty_like(b)
    c[bounded] = low + _nnls_gram(g_bb, b_b - g_bb @ low)
    if free.any():
        c[free] = w[:, -1] - w[:, :-1] @ c[bounded]
    return np.asarray(c * scale, dtype=np.float64)


def _nnls_gram(gram: FloatArray, rhs: FloatArray) -> FloatArray:
    """min x'Gx - 2 x'g with x >= 0 (G positive definite)."""
    r = linalg.cholesky(gram, lower=False, check_finite=False)
    z = linalg.solve_triangular(r, rhs, trans="T", check_finite=False)
    try:
        x, _ = optimize.nnls(r, z)
    except RuntimeError:  # its iteration limit (3 n): the slower BVLS, which has none
        x = optimize.lsq_linear(r, z, bounds=(0.0, np.inf), method="bvls").x
    return np.asarray(x, dtype=np.float64)


def solve_gram_sse(
    gram: FloatArray, rhs: FloatArray, lower: FloatArray
) -> tuple[FloatArray, float]:
    """:func:`solve_gram`'s coefficients c and the squared residual they leave, less the
    constant y'y: c'Gc - 2 c'g."""
    c = solve_gram(gram, rhs, lower)
    return c, float(c @ gram @ c) - 2.0 * float(c @ rhs)


@dataclass(frozen=True)
class PartDesign:
    """One trace's design and force with its training and held-out rows."""

    columns: Columns
    force_N: FloatArray
    train: BoolArray
    held: BoolArray


class GramDesign:
    """The training Gram matrix of a design over several parts, for fast trials.

    The design's rows are read in place, run by run of the masks, never gathered (a
    gathered copy of the training rows cost as much as the Gram matrix itself).

    Parameters
    ----------
    parts
        The design of each part (same columns in each), its force and masks.
    """

    def __init__(self, parts: Sequence[PartDesign]) -> None:
        self.parts = tuple(parts)
        self.lower = self.parts[0].columns.lower
        self._train_rows = [np.flatnonzero(p.train) for p in self.parts]
        self._held_rows = [np.flatnonzero(p.held) for p in self.parts]
        self._train_slices = [_slices(p.train) for p in self.parts]
        self._held_slices = [_slices(p.held) for p in self.parts]
        self._train_y = [p.force_N[p.train] for p in self.parts]
        self.gram, self.rhs = self._train_gram([p.columns.values for p in self.parts])
        self._yy = float(sum(float(y @ y) for y in self._train_y))
        self._n_train = sum(y.size for y in self._train_y)
        self._owned = False  # the parts' arrays are the caller's until a column is replaced

    def _train_gram(self, values: Sequence[FloatArray]) -> tuple[FloatArray, FloatArray]:
        """The training Gram matrix and right-hand side of designs ``values`` (one
        (rows, m) array per part) on this design's rows."""
        m = values[0].shape[1]
        gram, rhs = np.zeros((m, m)), np.zeros(m)
        for p, v, train in zip(self.parts, values, self._train_slices, strict=True):
            for run in train:
                gram += v[run].T @ v[run]
                rhs += p.force_N[run] @ v[run]
        return gram, rhs

    def _cross(self, part: int, b: FloatArray) -> FloatArray:
        """The design's training rows of ``part`` times ``b`` (those rows of other
        columns, in order), (m, k)."""
        v = self.parts[part].columns.values
        out = np.zeros((v.shape[1], b.shape[1]))
        at = 0
        for run in self._train_slices[part]:
            size = run.stop - run.start
            out += v[run].T @ b[at : at + size]
            at += size
        return out

    def _held_prediction(self, values: Sequence[FloatArray], coef: FloatArray) -> list[FloatArray]:
        """Each part's held-out rows of designs ``values`` times ``coef`` ((m,) or (m, k))."""
        out = []
        for v, held in zip(values, self._held_slices, strict=True):
            blocks = [v[run] @ coef for run in held]
            out.append(np.concatenate(blocks) if blocks else np.zeros((0, *coef.shape[1:])))
        return out

    @functools.cached_property
    def _held_y(self) -> FloatArray:
        return np.concatenate([p.force_N[p.held] for p in self.parts])

    def fit(self) -> FloatArray:
        """Coefficients of the design fitted on the training rows."""
        return solve_gram(self.gram, self.rhs, self.lower)

    def train_rms(self, theta: FloatArray) -> float:
        """Training RMS of the design with coefficients ``theta``."""
        return rms(
            np.concatenate([
                p.force_N[run] - p.columns.values[run] @ theta
                for p, train in zip(self.parts, self._train_slices, strict=True)
                for run in train
            ])
        )  # fmt: skip

    def held_residual(self, theta: FloatArray) -> FloatArray:
        """Held-out residual of the design with coefficients ``theta``."""
        values = [p.columns.values for p in self.parts]
        return self._held_y - np.concatenate(self._held_prediction(values, theta))

    def trial(self, extra: Sequence[Columns]) -> tuple[FloatArray, FloatArray]:
        """Coefficients and held-out residual of this design plus ``extra`` (one
        :class:`Columns` per part), fitted on the training rows."""
        return self.trials([extra])[0]

    def trials(self, extras: Sequence[Sequence[Columns]]) -> list[tuple[FloatArray, FloatArray]]:
        """:meth:`trial` of each of ``extras``, the design's rows read once for a batch
        of them (``BATCH_COLUMNS`` extra columns): a trial's cross products with the
        design and its held-out prediction are products of the whole design."""
        out: list[tuple[FloatArray, FloatArray]] = []
        batch: list[Sequence[Columns]] = []
        for extra in extras:
            if batch and sum(e[0].lower.size for e in [*batch, extra]) > BATCH_COLUMNS:
                out += self._trials(batch)
                batch = []
            batch.append(extra)
        return out + (self._trials(batch) if batch else [])

    def _trials(self, extras: Sequence[Sequence[Columns]]) -> list[tuple[FloatArray, FloatArray]]:
        m = self.lower.size
        thetas = [solve_gram(*system) for system in self._augmented(extras)]
        # the design's share of every trial's held-out prediction, the design read once
        coef = np.column_stack([t[:m] for t in thetas])
        shares = self._held_prediction([p.columns.values for p in self.parts], coef)
        out = []
        for k, (theta, extra) in enumerate(zip(thetas, extras, strict=True)):
            pred = [
                share[:, k] + np.take(e.values, rows, axis=0) @ theta[m:]
                for share, rows, e in zip(shares, self._held_rows, extra, strict=True)
            ]
            out.append((theta, self._held_y - np.concatenate(pred)))
        return out

    def trial_train_rms(self, extra: Sequence[Columns]) -> tuple[FloatArray, float]:
        """Coefficients and training RMS of this design plus ``extra``, from the Gram
        matrix alone (no residual over the training rows)."""
        theta, sse = solve_gram_sse(*self.augmented(extra))
        return theta, float(np.sqrt(max(self._yy + sse, 0.0) / max(self._n_train, 1)))

    def column_replaced(
        self, i: int, values: Sequence[FloatArray]
    ) -> tuple[FloatArray, FloatArray]:
        """The training Gram matrix and right-hand side with column ``i`` replaced by
        ``values`` (one full-length column per part), for :func:`solve_gram_sse`."""
        train = [np.take(v, rows) for v, rows in zip(values, self._train_rows, strict=True)]
        gram, rhs = self.gram.copy(), self.rhs.copy()
        gram[i, :] = gram[:, i] = sum(
            (self._cross(part, c[:, None])[:, 0] for part, c in enumerate(train)),
            np.zeros(self.lower.size),
        )
        gram[i, i] = sum(float(c @ c) for c in train)
        rhs[i] = sum(float(c @ y) for c, y in zip(train, self._train_y, strict=True))
        return gram, rhs

    def refitted(self, values: Sequence[FloatArray]) -> tuple[FloatArray, FloatArray]:
        """Coefficients and held-out residual of another design on the same rows and
        bounds (``values``: one (rows, m) array per part, this design's columns through
        a filter), fitted on the training rows (its rows read in place)."""
        gram, rhs = self._train_gram(values)
        theta = solve_gram(gram, rhs, self.lower)
        return theta, self._held_y - np.concatenate(self._held_prediction(values, theta))

    def jackknife(self, groups: int) -> list[FloatArray]:
        """The coefficients fitted with each of ``groups`` contiguous groups of the training
        rows (in time, part after part) left out in turn (a delete-a-group jackknife)."""
        rows = np.concatenate(self._train_rows)
        part = np.concatenate([np.full(r.size, p) for p, r in enumerate(self._train_rows)])
        edges = np.linspace(0, rows.size, groups + 1).astype(int)
        out = []
        for lo, hi in itertools.pairwise(edges):
            gram, rhs = self.gram.copy(), self.rhs.copy()
            for p in range(len(self.parts)):
                taken = rows[lo:hi][part[lo:hi] == p]
                if taken.size:
                    a = self.parts[p].columns.values[taken]
                    gram -= a.T @ a
                    rhs -= self.parts[p].force_N[taken] @ a
            out.append(solve_gram(gram, rhs, self.lower))
        return out

    def cross_products(
        self, values: Sequence[FloatArray]
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """For candidate columns ``values`` (one (rows, T) array per part): their training
        cross products with the design (m, T), with each other (T, T) and with the
        force (T,), the design read once for all of them (:meth:`column_replaced` reads
        it for each)."""
        m, t = self.lower.size, values[0].shape[1]
        design, inner, rhs = np.zeros((m, t)), np.zeros((t, t)), np.zeros(t)
        for part, (rows, y, v) in enumerate(
            zip(self._train_rows, self._train_y, values, strict=True)
        ):
            c = np.take(v, rows, axis=0)
            design += self._cross(part, c)
            inner += c.T @ c
            rhs += y @ c
        return design, inner, rhs

    def replace_column(
        self, i: int, values: Sequence[FloatArray],
        replaced: tuple[FloatArray, FloatArray] | None = None,
    ) -> None:  # fmt: skip
        """Replace column ``i`` by ``values`` (one full-length column per part) in place;
        ``replaced``: :meth:`column_replaced`'s result for them, if already at hand."""
        self.gram, self.rhs = replaced or self.column_replaced(i, values)
        if not self._owned:  # the caller's arrays are left as they were
            self.parts = tuple(
                dataclasses.replace(
                    p, columns=Columns(p.columns.values.copy(order="K"), p.columns.lower)
                )
                for p in self.parts
            )
            self._owned = True
        for part, v in zip(self.parts, values, strict=True):
            part.columns.values[:, i] = v

    def left_out(
        self, extra: Sequence[Columns], events: Sequence[Sequence[IntArray]], folds: int
    ) -> tuple[FloatArray, FloatArray]:
        """Residuals at the ``events`` (row indices, per part) of this design without
        and with ``extra`` (one :class:`Columns` per part), each event's from the fit on
        the training rows less its fold's: the events, part by part in order, are dealt
        into at most ``folds`` folds. Returns the residuals of the events in order."""
        gram, rhs, lower = self.augmented(extra)
        m = self.lower.size
        order = [(p, rows) for p, part_events in enumerate(events) for rows in part_events]
        if not order:
            return np.zeros(0), np.zeros(0)
        n_folds = min(folds, len(order))
        base: list[FloatArray] = [np.zeros(0)] * len(order)
        new: list[FloatArray] = [np.zeros(0)] * len(order)
        for fold in range(n_folds):
            g, r = gram.copy(), rhs.copy()
            for p, rows in order[fold::n_folds]:
                train = rows[self.parts[p].train[rows]]
                a = np.column_stack([self.parts[p].columns.values[train], extra[p].values[train]])
                g -= a.T @ a
                r -= a.T @ self.parts[p].force_N[train]
            theta = solve_gram(g, r, lower)
            theta0 = solve_gram(g[:m, :m], r[:m], lower[:m])
            for i in range(fold, len(order), n_folds):
                p, rows = order[i]
                a, b = self.parts[p].columns.values[rows], extra[p].values[rows]
                y = self.parts[p].force_N[rows]
                base[i], new[i] = y - a @ theta0, y - a @ theta[:m] - b @ theta[m:]
        return np.concatenate(base), np.concatenate(new)

    def augmented(self, extra: Sequence[Columns]) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The training Gram matrix, right-hand side and bounds with ``extra`` (one
        :class:`Columns` per part) added."""
        return self._augmented([extra])[0]

    def _augmented(
        self, extras: Sequence[Sequence[Columns]]
    ) -> list[tuple[FloatArray, FloatArray, FloatArray]]:
        """:meth:`augmented` of each of ``extras``, the design's rows read once for all."""
        m = self.lower.size
        edges = np.cumsum([0] + [e[0].lower.size for e in extras])
        cross, rhs = np.zeros((m, edges[-1])), np.zeros(edges[-1])
        inner = [np.zeros((hi - lo, hi - lo)) for lo, hi in itertools.pairwise(edges)]
        for part, (rows, y) in enumerate(zip(self._train_rows, self._train_y, strict=True)):
            b = np.empty((rows.size, edges[-1]))
            for k, extra in enumerate(extras):
                b[:, edges[k] : edges[k + 1]] = np.take(extra[part].values, rows, axis=0)
                inner[k] += b[:, edges[k] : edges[k + 1]].T @ b[:, edges[k] : edges[k + 1]]
            cross += self._cross(part, b)
            rhs += y @ b
        out = []
        for k, extra in enumerate(extras):
            c = cross[:, edges[k] : edges[k + 1]]
            out.append((
                np.block([[self.gram, c], [c.T, inner[k]]]),
                np.concatenate([self.rhs, rhs[edges[k] : edges[k + 1]]]),
                np.concatenate([self.lower, extra[0].lower]),
            ))  # fmt: skip
        return out


def runs(mask: BoolArray, gap: int = 1) -> list[IntArray]:
    """The rows of ``mask``'s runs, runs less than ``gap`` rows apart merged."""
    rows = np.flatnonzero(mask)
    if rows.size == 0:
        return []
    return np.split(rows, np.flatnonzero(np.diff(rows) > gap) + 1)


def _slices(mask: BoolArray) -> list[slice]:
    """The runs of ``mask``'s rows as slices, in order."""
    return [slice(int(r[0]), int(r[-1]) + 1) for r in runs(mask)]


def every_row(parts: Sequence[PartDesign]) -> list[PartDesign]:
    """``parts`` fitted on all their rows, training and held out (held out: as before)."""
    return [PartDesign(p.columns, p.force_N, p.train | p.held, p.held) for p in parts]
