"""The blind baseline's elements off the grid: a GMS whose break-aways lie between the
grid's points is fitted with elements at its own break-aways (baseline.refine_knots).

The truth is the independent generator's play operator (tests/indepfriction.py), not the
diagnosis's kernel."""

from __future__ import annotations

import numpy as np
import pytest
from indepfriction import play_operator

import gms_comp.measured.diagnosis.baseline as baseline_module
from gms_comp.gms import GmsParams
from gms_comp.measured.diagnosis.baseline import fit_baseline
from gms_comp.measured.diagnosis.config import DiagnosisConfig
from gms_comp.measured.diagnosis.prepare import prepare
from gms_comp.measured.traces import Trace

RATE_HZ = 2000.0
TRUE_BREAKAWAY_M = np.array([0.9e-6, 4.3e-6, 23e-6])
TRUE_LIMIT_N = np.array([3.0, 5.0, 4.0])
NOISE_N = 0.01


def _motion() -> tuple[np.ndarray, np.ndarray]:
    """Reversals of many amplitudes (1-200 um, each break-away crossed at several
    amplitudes) at a few mm/s, with rests between them."""
    t_seg = np.arange(0.0, 1.0, 1.0 / RATE_HZ)
    pieces = [np.zeros(int(0.2 * RATE_HZ))]
    for amplitude in np.geomspace(1e-6, 200e-6, 14):
        for sign in (1.0, -1.0):
            pieces.append(sign * amplitude * np.sin(2 * np.pi * 2.0 * t_seg))
            pieces.append(np.zeros(int(0.2 * RATE_HZ)))
    x = np.concatenate(pieces)
    return np.arange(x.size) / RATE_HZ, x


def _fitted(knot_rounds: int, monkeypatch: pytest.MonkeyPatch) -> tuple[GmsParams, float]:
    monkeypatch.setattr(baseline_module, "KNOT_ROUNDS", knot_rounds)
    t, x = _motion()
    q = 1e-9
    xq = np.round(x / q) * q
    step = np.diff(x, prepend=x[0])
    force = play_operator(step, TRUE_LIMIT_N / TRUE_BREAKAWAY_M, TRUE_BREAKAWAY_M, np.ones(x.size))
    force = force + np.random.default_rng(0).normal(0.0, NOISE_N, x.size)  # 0.1 % of the level
    cfg = DiagnosisConfig()
    prepared = prepare(Trace("knots", t, xq, force), "friction", None, cfg)
    baseline = fit_baseline(prepared, cfg, None)
    return baseline.gms, baseline.heldout_rms_N


def _misplaced(gms: GmsParams) -> list[float]:
    """The true break-aways with less than 80 % of their limit fitted within 10 %."""
    limit = gms.limit_N[gms.limit_N > 0]
    fitted = limit / gms.stiffness_N_per_m[gms.limit_N > 0]
    return [
        float(d)
        for d, w in zip(TRUE_BREAKAWAY_M, TRUE_LIMIT_N, strict=True)
        if limit[np.abs(np.log(fitted / d)) < np.log(1.1)].sum() < 0.8 * w
    ]


def test_off_grid_breakaways_are_found_off_the_grid(monkeypatch: pytest.MonkeyPatch) -> None:
    gms, heldout_rms = _fitted(baseline_module.KNOT_ROUNDS, monkeypatch)
    assert _misplaced(gms) == [], (gms.limit_N / gms.stiffness_N_per_m, gms.limit_N)
    assert abs(gms.limit_N.sum() - TRUE_LIMIT_N.sum()) < 0.02 * TRUE_LIMIT_N.sum()
    # near the noise (the last knot step is 5 %: each element is carried by two knots
    # within 2.5 % either side of it); on the grid alone 12 x the noise
    assert heldout_rms < 2.5 * NOISE_N


def test_on_the_grid_alone_they_are_not(monkeypatch: pytest.MonkeyPatch) -> None:
    # what the test above would see without the knots moved: the limits on grid points
    # either side of a true break-away (so the test above can fail)
    gms, heldout_rms = _fitted(0, monkeypatch)
    assert _misplaced(gms) != []
    assert heldout_rms > 5 * NOISE_N
