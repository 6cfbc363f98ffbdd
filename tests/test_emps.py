"""EMPS benchmark: the published IDIM-LS numbers (Janot, Gautier, Brunot 2019, §3.4, §4.2)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gms_comp.app import emps
from gms_comp.measured.traces import load_trace

EMPS = Path(__file__).resolve().parents[2] / "shared" / "data" / "emps"
pytestmark = pytest.mark.skipif(
    not (EMPS / "DATA_EMPS.mat").is_file(), reason=f"EMPS data not found in {EMPS}"
)


@pytest.fixture(scope="module")
def train_fit() -> emps.IdimResult:
    return emps.idim_ls(load_trace(EMPS / "DATA_EMPS.mat"))


def test_idim_ls_parameters_match_the_paper(train_fit: emps.IdimResult) -> None:
    np.testing.assert_allclose(train_fit.theta, [95.1089, 203.5034, 20.3935, -3.1648], atol=5e-5)
    np.testing.assert_allclose(train_fit.std, [0.1085, 1.1460, 0.1012, 0.0444], atol=5e-5)


def test_idim_ls_error_figures_match_the_paper(train_fit: emps.IdimResult) -> None:
    assert train_fit.relative_error_pct == pytest.approx(4.0834, abs=5e-5)
    assert train_fit.error_norm == pytest.approx(108.7569, abs=5e-5)
    assert train_fit.condition_number == pytest.approx(25.9883, abs=5e-5)


def test_cross_test_matches_the_paper(train_fit: emps.IdimResult) -> None:
    ctv = emps.cross_test(train_fit, load_trace(EMPS / "DATA_EMPS_PULSES.mat"))
    assert ctv.relative_error_pct == pytest.approx(5.9824, abs=5e-5)
    assert ctv.error_norm == pytest.approx(169.4876, abs=5e-5)
    assert ctv.condition_number == pytest.approx(26.0217, abs=5e-5)


def test_asymmetric_model_matches_the_paper() -> None:
    fit = emps.idim_ls(load_trace(EMPS / "DATA_EMPS.mat"), asymmetric=True)
    np.testing.assert_allclose(
        fit.theta, [95.1540, 166.7061, 20.1440, 240.4236, 20.6277], atol=5e-5
    )
    assert fit.relative_error_pct == pytest.approx(3.1117, abs=5e-5)
    assert fit.error_norm == pytest.approx(82.8778, abs=5e-5)


def test_relative_error_of_a_perfect_prediction_is_zero() -> None:
    y = np.sin(np.linspace(0, 20, 2000))
    assert emps.relative_error_pct(y, y) == 0.0
    assert emps.relative_error_pct(y, 0 * y) == pytest.approx(100.0, rel=1e-9)
