"""The Gram-matrix trials against a bounded least-squares solve of the whole design."""

from __future__ import annotations

import numpy as np
from scipy import optimize

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
    gram.replace_column(2, [new])
    theta = rebuilt.fit()
    assert np.allclose(gram.fit(), theta)
    assert np.allclose(gram.held_residual(theta), rebuilt.held_residual(theta))
    # and it fits what a bounded least squares of the rebuilt design gives
    expected = optimize.lsq_linear(
        values[p.train], p.force_N[p.train], bounds=(p.columns.lower, np.inf)
    ).x
    assert np.allclose(theta, expected, atol=1e-8)
