"""The reduction recovers known element sets, and reduces the ball model within the targets."""

from __future__ import annotations

import numpy as np
import pytest

from gms_comp.config import config_hash, default_config_path, load_ball_config
from gms_comp.gms import GmsParams, simulate
from gms_comp.reduction import (
    TableConfig,
    fidelity,
    fit_elements,
    fit_span,
    random_path,
    reduce_to_gms,
    with_reference,
)

C_V = 1.2
BREAKPOINTS_m = np.geomspace(1e-7, 1e-4, 6)
STIFFNESS_N_per_m = np.array([4e4, 1e4, 3e3, 8e2, 3e2, 1e2])


def known() -> GmsParams:
    return GmsParams(STIFFNESS_N_per_m, STIFFNESS_N_per_m * BREAKPOINTS_m, slip_level=C_V)


def known_curve() -> tuple[np.ndarray, np.ndarray]:
    """Virgin curve of the known set, written out: k x while stuck, C_v k Delta after."""
    x = np.geomspace(1e-9, 1e-3, 200)
    stuck = x[:, None] <= BREAKPOINTS_m[None, :]
    force = np.where(stuck, x[:, None], C_V * BREAKPOINTS_m[None, :]) @ STIFFNESS_N_per_m
    return x, force


def training() -> list[tuple[tuple[np.ndarray, np.ndarray], np.ndarray]]:
    path = random_path(np.random.default_rng(1), 15, (1e-7, 3e-4), 0.01, 20_000.0)
    return with_reference(lambda x, v: simulate(known(), x, v)[0], [path])


def template() -> GmsParams:
    return GmsParams(np.ones(1), np.ones(1), slip_level=C_V)


@pytest.mark.parametrize("with_paths", [False, True])
def test_known_elements_are_recovered(with_paths: bool) -> None:
    paths = training() if with_paths else []
    model, residual = fit_elements(BREAKPOINTS_m, template(), known_curve(), paths)
    np.testing.assert_allclose(model.stiffness_N_per_m, STIFFNESS_N_per_m, rtol=1e-6)
    np.testing.assert_allclose(model.limit_N, STIFFNESS_N_per_m * BREAKPOINTS_m, rtol=1e-6)
    assert residual < 1e-9


def test_span_search_finds_the_true_span() -> None:
    spans = [(1e-7, 1e-5), (3e-8, 1e-4), (1e-7, 1e-4), (1e-6, 1e-3)]
    model = fit_span(6, template(), known_curve(), training(), spans)
    np.testing.assert_allclose(model.stiffness_N_per_m, STIFFNESS_N_per_m, rtol=1e-6)


def test_fidelity_is_zero_against_itself_and_exact_for_scaled_limits() -> None:
    refs = training()
    assert fidelity(known(), refs, 1.0).rms_rel == pytest.approx(0.0, abs=1e-12)
    # Every element 1 % stronger: the force is 1 % higher everywhere, so the largest
    # error is 1 % of the sliding force, reached in full sliding.
    p = known()
    bigger = GmsParams(1.01 * p.stiffness_N_per_m, 1.01 * p.limit_N, slip_level=C_V)
    sliding_N = C_V * float(p.limit_N.sum())
    assert fidelity(bigger, refs, sliding_N).max_rel == pytest.approx(0.01, rel=1e-6)


def test_random_path_moves_at_the_given_speed_within_the_amplitudes() -> None:
    x, v = random_path(np.random.default_rng(2), 40, (1e-6, 1e-4), 0.02, 10_000.0)
    moving = v != 0
    assert set(np.unique(np.abs(v[moving]))) == {0.02}
    assert np.all(np.abs(np.diff(x)) <= 0.02 / 10_000.0 * (1 + 1e-9))
    assert np.all(np.diff(x)[~moving[1:]] == 0)
    turns = np.flatnonzero(np.diff(np.sign(v[moving])) != 0)
    assert len(turns) > 5


@pytest.mark.parametrize(("n", "rms_target"), [(8, 0.02)])
def test_ball_model_reduction_meets_the_target(n: int, rms_target: float) -> None:
    table = reduce_to_gms(load_ball_config(), n, TableConfig())
    assert 1 <= table.n_elements <= n
    assert table.fidelity.rms_rel <= rms_target
    assert table.source_sha256 == config_hash(default_config_path())
    # The sliding force of the table is the ball set's, C_v sum W_i ~ 0.277 N (spec).
    assert C_V * float(table.params.limit_N.sum()) == pytest.approx(0.277, rel=0.03)
