"""The interval arithmetic of the diagnosis (docs/diagnosis-method.md, section 6): the
jackknife's refits and the clipping of an interval. How often the intervals hold the
truth is measured by rate (tests/test_diagnosis_rates.py)."""

from __future__ import annotations

import itertools
import math
from types import SimpleNamespace
from typing import Any

import numpy as np

from gms_comp.measured.diagnosis import intervals as iv
from gms_comp.measured.diagnosis.candidates import Option
from gms_comp.measured.diagnosis.design import Columns, GramDesign, PartDesign
from gms_comp.runtime import effects as fx


def _parts(sample_time_s: float) -> Any:
    t = np.arange(200) * sample_time_s
    x = 1e-3 * np.sin(t)
    ctx = fx.Context.along(t, x, np.gradient(x, t), np.zeros_like(t), np.zeros_like(t))
    return [SimpleNamespace(ctx=ctx)]


def test_the_jackknife_refits_leave_out_each_block_of_training_rows_in_turn() -> None:
    rng = np.random.default_rng(3)
    parts, rows = [], []
    for n in (120, 80):  # two parts: the blocks run on across them
        a = rng.normal(size=(n, 3))
        y = a @ np.array([1.0, -2.0, 0.5]) + rng.normal(size=n)
        train = rng.random(n) < 0.7
        parts.append(PartDesign(Columns(a, np.full(3, -np.inf)), y, train, ~train))
        rows += [(a[i], y[i]) for i in np.flatnonzero(train)]
    replicates = GramDesign(parts).jackknife(5)
    edges = np.linspace(0, len(rows), 6).astype(int)
    for (lo, hi), got in zip(itertools.pairwise(edges), replicates, strict=True):
        kept = rows[:lo] + rows[hi:]
        a = np.array([r[0] for r in kept])
        y = np.array([r[1] for r in kept])
        np.testing.assert_allclose(got, np.linalg.lstsq(a, y, rcond=None)[0], rtol=1e-9)


def test_a_shape_interval_of_a_huge_spread_is_finite_clipped_at_its_bounds_and_flagged() -> None:
    # unknown_stroke_profile-403: a lag's jackknife spread 1e6 times its size once
    # overflowed e^(relative)
    parts = _parts(1e-3)
    opt = Option(fx.DriveLag, {"lag_s": 2e-3})
    found = iv._bounded(opt, 0, {"lag_s": 2e-3}, {"lag_s": 1e3}, 2.0, 0.06, 1e-5, parts)
    lo_b, hi_b = opt.policy.shape_bounds(parts[0].ctx, 1e-5)["lag_s"]
    assert found.bounds["lag_s"] == (lo_b, hi_b)
    assert found.at_bound == ("lag_s",)


def test_a_narrow_interval_is_at_least_the_model_form_share_and_not_flagged() -> None:
    parts = _parts(1e-3)
    opt = Option(fx.DriveLag, {"lag_s": 2e-3})
    found = iv._bounded(opt, 0, {"lag_s": 2e-3}, {"lag_s": 0.0}, 2.0, 0.06, 1e-5, parts)
    assert found.bounds == {}  # no spread: a figure of the trace alone, no interval
    found = iv._bounded(opt, 0, {"lag_s": 2e-3}, {"lag_s": 1e-9}, 2.0, 0.06, 1e-5, parts)
    lo, hi = found.bounds["lag_s"]
    assert math.isclose(lo, 2e-3 * math.exp(-0.06)) and math.isclose(hi, 2e-3 * math.exp(0.06))
    assert found.at_bound == ()
