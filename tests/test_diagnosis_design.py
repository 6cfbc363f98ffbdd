"""The Gram-matrix trials against a bounded least-squares solve of the whole design."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import optimize

from gms_comp.measured.diagnosis import design
from gms_comp.measured.diagnosis.design import Columns, GramDesign, PartDesign


def _problem(seed: int) -> tuple[list[PartDesign], list[Columns], np.ndarray]:
    rng = np.random.default_rng(seed)
    n, m, q = 3000, 5, 2
    a = rng.normal(size=(n, m))
    b = rng.normal(size=(n, q))
    truth = np.array([1.0, 0.5, 0.0, 2.0, -1.0, 0.7, -0.3])
    y = np.column_stack([a, b]) @ truth + rng.normal(0.0, 0.1, n)
    train = (np.arange(n) // 100) % 3 != 1
    lower = np.array([0.0, 0.0, 0.0, -np.inf, -np.inf])
    part = PartDesign(Columns(a, lower), y, train, ~train)
    extra = Columns(b, np.array([0.0, -np.inf]))
    return [part], [extra], truth


def test_trial_matches_a_bounded_least_squares_of_the_whole_design() -> None:
    for seed in range(3):
        parts, extra, _ = _problem(seed)
        p = parts[0]
        full = np.column_stack([p.columns.values, extra[0].values])
        lower = np.concatenate([p.columns.lower, extra[0].lower])
        expected = optimize.lsq_linear(
            full[p.train], p.force_N[p.train], bounds=(lower, np.full(lower.size, np.inf))
        ).x
        gram = GramDesign(parts)
        theta, held = gram.trial(extra)
        theta2, train_rms = gram.trial_train_rms(extra)
        assert np.allclose(theta, expected, atol=1e-8)
        assert np.allclose(theta2, expected, atol=1e-8)
        assert np.allclose(held, p.force_N[p.held] - full[p.held] @ expected, atol=1e-8)
        residual = p.force_N[p.train] - full[p.train] @ expected
        assert abs(train_rms - np.sqrt(np.mean(residual**2))) < 1e-9


def test_trials_in_batches_are_the_trials_one_by_one(monkeypatch: pytest.MonkeyPatch) -> None:
    # two parts, extras of one to three columns, split over several batches
    rng = np.random.default_rng(11)
    parts: list[PartDesign] = []
    extras: list[list[Columns]] = [[] for _ in range(7)]
    for n in (2500, 1700):
        p = _problem(int(rng.integers(100)))[0][0]
        cut = PartDesign(
            Columns(p.columns.values[:n], p.columns.lower), p.force_N[:n], p.train[:n],
            p.held[:n],
        )  # fmt: skip
        parts.append(cut)
        for k, extra in enumerate(extras):
            q = 1 + k % 3
            extra.append(
                Columns(rng.normal(size=(n, q)), np.where(np.arange(q) == 0, 0.0, -np.inf))
            )
    gram = GramDesign(parts)
    monkeypatch.setattr(design, "BATCH_COLUMNS", 4)
    batched = gram.trials(extras)
    for extra, (theta, held) in zip(extras, batched, strict=True):
        full = [
            np.column_stack([p.columns.values, e.values]) for p, e in zip(parts, extra, strict=True)
        ]
        train = np.vstack([f[p.train] for f, p in zip(full, parts, strict=True)])
        lower = np.concatenate([parts[0].columns.lower, extra[0].lower])
        y = np.concatenate([p.force_N[p.train] for p in parts])
        expected = optimize.lsq_linear(train, y, bounds=(lower, np.full(lower.size, np.inf))).x
        assert np.allclose(theta, expected, atol=1e-8)
        one = gram.trial(extra)
        assert np.allclose(theta, one[0], rtol=1e-12, atol=1e-12)
        assert np.allclose(held, one[1], rtol=1e-12, atol=1e-12)
        held_rows = np.concatenate([f[p.held] for f, p in zip(full, parts, strict=True)])
        y_held = np.concatenate([p.force_N[p.held] for p in parts])
        assert np.allclose(held, y_held - held_rows @ expected, atol=1e-8)


def test_a_refitted_design_reads_its_rows_run_by_run() -> None:
    # another design on the same rows (the columns squared): a bounded least squares of
    # its training rows, scored on its held-out rows, whatever the runs of the masks
    parts, _, _ = _problem(4)
    p = parts[0]
    rng = np.random.default_rng(4)
    for train in (p.train, rng.random(p.train.size) < 0.6):
        part = PartDesign(p.columns, p.force_N, train, ~train)
        other = part.columns.values**2
        expected = optimize.lsq_linear(
            other[train], p.force_N[train], bounds=(part.columns.lower, np.inf)
        ).x
        theta, held = GramDesign([part]).refitted([other])
        assert np.allclose(theta, expected, atol=1e-8)
        assert np.allclose(held, p.force_N[~train] - other[~train] @ expected, atol=1e-8)


def test_a_replaced_column_equals_the_design_built_with_it() -> None:
    parts, _, _ = _problem(5)
    p = parts[0]
    new = np.random.default_rng(9).normal(size=p.force_N.size)
    gram = GramDesign(parts)
    g2, r2 = gram.column_replaced(2, [new])
    values = p.columns.values.copy()
    values[:, 2] = new
    rebuilt = GramDesign([PartDesign(Columns(values, p.columns.lower), p.force_N, p.train, p.held)])
    assert np.allclose(g2, rebuilt.gram) and np.allclose(r2, rebuilt.rhs)
    assert not np.allclose(gram.gram, rebuilt.gram)  # only a trial: the design is unchanged
    before = p.columns.values.copy()
    gram.replace_column(2, [new])
    theta = rebuilt.fit()
    assert np.allclose(gram.fit(), theta)
    assert np.allclose(gram.held_residual(theta), rebuilt.held_residual(theta))
    assert gram.train_rms(theta) == pytest.approx(rebuilt.train_rms(theta), rel=1e-12)
    assert np.array_equal(p.columns.values, before)  # the caller's design is left as it was
    # and it fits what a bounded least squares of the rebuilt design gives
    expected = optimize.lsq_linear(
        values[p.train], p.force_N[p.train], bounds=(p.columns.lower, np.inf)
    ).x
    assert np.allclose(theta, expected, atol=1e-8)


def _events(n: int, rng: np.random.Generator, count: int) -> list[np.ndarray]:
    starts = np.sort(rng.choice(np.arange(0, n - 40, 60), size=count, replace=False))
    return [np.arange(s, s + int(rng.integers(5, 40))) for s in starts]


def test_left_out_residuals_are_a_bounded_fit_without_each_fold() -> None:
    """Every event's residuals come from a bounded least squares of the whole design on
    the training rows less its fold's events (scipy's, from scratch)."""
    for seed, folds in ((0, 3), (1, 10), (2, 4)):
        parts, extra, _ = _problem(seed)
        p = parts[0]
        events = _events(p.force_N.size, np.random.default_rng(seed + 10), 9)
        base, new = GramDesign(parts).left_out(extra, [events], folds)
        full = np.column_stack([p.columns.values, extra[0].values])
        lower = np.concatenate([p.columns.lower, extra[0].lower])
        m = p.columns.values.shape[1]
        k = min(folds, len(events))
        expected_base, expected_new = [], []
        for i, rows in enumerate(events):
            keep = p.train.copy()
            for other in events[i % k :: k]:
                keep[other] = False
            with_extra = optimize.lsq_linear(
                full[keep], p.force_N[keep], bounds=(lower, np.full(lower.size, np.inf))
            ).x
            without = optimize.lsq_linear(
                full[keep][:, :m], p.force_N[keep], bounds=(lower[:m], np.full(m, np.inf))
            ).x
            expected_new.append(p.force_N[rows] - full[rows] @ with_extra)
            expected_base.append(p.force_N[rows] - full[rows][:, :m] @ without)
        assert np.allclose(new, np.concatenate(expected_new), atol=1e-7)
        assert np.allclose(base, np.concatenate(expected_base), atol=1e-7)


def test_an_event_left_out_is_judged_by_a_fit_that_never_saw_it() -> None:
    """One event per fold: a disturbance at an event moves its own residuals by exactly
    the disturbance (its fit did not see it), and every other event's by some."""
    parts, extra, _ = _problem(3)
    p = parts[0]
    events = _events(p.force_N.size, np.random.default_rng(4), 6)
    base, new = GramDesign(parts).left_out(extra, [events], len(events))
    bumped = p.force_N.copy()
    bumped[events[2]] += 50.0
    part = PartDesign(p.columns, bumped, p.train, p.held)
    base2, new2 = GramDesign([part]).left_out(extra, [events], len(events))
    sizes = np.cumsum([0] + [e.size for e in events])
    own = slice(sizes[2], sizes[3])
    assert np.allclose(new2[own] - new[own], 50.0) and np.allclose(base2[own] - base[own], 50.0)
    others = np.ones(new.size, dtype=bool)
    others[own] = False
    if np.any(p.train[events[2]]):  # its rows trained the other folds' fits
        assert np.max(np.abs(new2[others] - new[others])) > 1e-3


def test_a_design_is_the_same_from_contiguous_or_transposed_columns() -> None:
    """Rows are read in place, run by run of the masks, from contiguous columns or from a
    filtered design's transposed rows: the fit, its training RMS and held-out residual
    agree to rounding either way, and the RMS is the residual's."""
    parts, _, _ = _problem(2)
    p = parts[0]
    transposed = np.ascontiguousarray(p.columns.values.T).T
    assert not transposed.flags.c_contiguous
    other = PartDesign(Columns(transposed, p.columns.lower), p.force_N, p.train, p.held)
    a, b = GramDesign(parts), GramDesign([other])
    theta = a.fit()
    np.testing.assert_allclose(b.fit(), theta, rtol=1e-12, atol=1e-12 * np.abs(theta).max())
    assert a.train_rms(theta) == pytest.approx(b.train_rms(theta), rel=1e-12)
    np.testing.assert_allclose(a.held_residual(theta), b.held_residual(theta), atol=1e-12)
    residual = p.force_N[p.train] - p.columns.values[p.train] @ theta
    assert abs(a.train_rms(theta) - np.sqrt(np.mean(residual**2))) < 1e-12


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    m=st.integers(1, 22),
    free_share=st.floats(0.0, 1.0),
)
def test_the_bounded_solve_is_lsq_linear_s(seed: int, m: int, free_share: float) -> None:
    # columns of sizes 1e-3 to 1e3, lower bounds 0, negative or positive where bounded,
    # -inf where free; the answer must be scipy's BVLS on the whole design's rows
    rng = np.random.default_rng(seed)
    n = 4 * m + 10
    a = rng.normal(size=(n, m)) * 10.0 ** rng.uniform(-3, 3, m)
    y = a @ rng.normal(size=m) + rng.normal(0.0, 1.0, n)
    lower = np.where(rng.uniform(size=m) < 0.5, 0.0, rng.normal(size=m))
    lower = np.where(rng.uniform(size=m) < free_share, -np.inf, lower)
    expected = optimize.lsq_linear(
        a, y, bounds=(lower, np.full(m, np.inf)), method="bvls", tol=1e-14
    ).x
    got = design.solve(a, y, lower)
    assert np.all(got >= lower - 1e-9 * np.abs(lower))
    cost = float(np.sum((a @ got - y) ** 2))
    best = float(np.sum((a @ expected - y) ** 2))
    assert cost <= best * (1 + 1e-9) + 1e-12
    assert np.allclose(a @ got, a @ expected, rtol=1e-6, atol=1e-6 * np.linalg.norm(y))


def test_the_bounded_solve_falls_back_to_bvls_at_the_nnls_iteration_limit(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # scipy's nnls raises at its iteration limit (3 n); the answer must still be the optimum
    rng = np.random.default_rng(7)
    a = rng.normal(size=(60, 8))
    y = a @ rng.normal(size=8) + rng.normal(0.0, 0.5, 60)
    lower = np.array([0.0, 0.0, -1.0, 0.5, 0.0, -np.inf, 0.0, -np.inf])
    expected = design.solve(a, y, lower)

    def limit(*_: object, **__: object) -> None:
        raise RuntimeError("Maximum number of iterations reached.")

    monkeypatch.setattr(design.optimize, "nnls", limit)
    got = design.solve(a, y, lower)
    assert np.any(np.isclose(expected, lower))  # some bound is active: not a plain solve
    assert np.allclose(got, expected, rtol=1e-8, atol=1e-10)


def test_an_empty_or_repeated_column_leaves_the_bounded_solve_defined() -> None:
    # a zero column and a duplicated one: the ridge keeps the solve finite, the fit exact
    rng = np.random.default_rng(3)
    base = rng.normal(size=(200, 3))
    a = np.column_stack([base, np.zeros(200), base[:, 0]])
    y = base @ np.array([1.0, -2.0, 0.5])
    got = design.solve(a, y, np.array([0.0, -np.inf, -np.inf, 0.0, 0.0]))
    assert np.all(np.isfinite(got))
    assert np.allclose(a @ got, y, atol=1e-6)
    assert abs(got[3]) < 1e-6
