"""A dwell column from rest (elements stepped only while the raised ones differ) is the
per-sample kernel's, bit for bit."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from gms_comp.gms import GmsParams, simulate_elements
from gms_comp.runtime import effects as fx
from gms_comp.runtime.effects import dwell_time
from gms_comp.runtime.effects.path import REST_HOLD_S


def _path() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rests of 0.02-1 s between strokes of 1-200 um either way and micrometre jiggles,
    read through a 5 nm encoder at 2 kHz: after a short stroke the widest elements have
    not slipped when the next start comes."""
    rng = np.random.default_rng(7)
    dt, pieces, x0 = 5e-4, [], 0.0
    for _ in range(14):
        rest = int(rng.uniform(0.02, 1.0) / dt)
        pieces.append(np.full(rest, x0))
        n = int(rng.uniform(0.05, 0.3) / dt)
        s = np.linspace(0.0, 1.0, n)
        stroke = rng.choice([-1.0, 1.0]) * rng.uniform(1e-6, 2e-4)
        jiggle = 2e-6 * np.sin(2 * np.pi * rng.integers(1, 4) * s) * rng.integers(0, 2)
        pieces.append(x0 + stroke * (3 * s**2 - 2 * s**3) + jiggle)
        x0 = float(pieces[-1][-1])
    x = np.round(np.concatenate(pieces) / 5e-9) * 5e-9
    t = np.arange(x.size) * dt
    return t, x, np.gradient(x, t)


@pytest.mark.parametrize("keep", [0.0, 1.0])
@pytest.mark.parametrize("law", [False, True])
@pytest.mark.parametrize(("tau", "reach"), [(1e-4, 1.5), (0.05, 0.3), (0.4, 0.03), (3.0, 0.05)])
def test_a_dwell_column_from_rest_is_the_per_sample_kernels(
    tau: float, reach: float, law: bool, keep: float
) -> None:
    t, x, v = _path()
    delta = np.array([0.5e-6, 2e-6, 8e-6, 40e-6])  # the widest rarely slips
    w = np.array([1.0, 2.0, 1.5, 0.7])
    gms = GmsParams(w / delta, w, slip_level=1.2, transition_velocity_m_s=2e-4,
                    limit_follows_level=law)  # fmt: skip
    ctx = fx.Context.along(t, x, v, 0 * t, 0 * t, 1e-5, 5e-9, 7.5e-9)
    ctx = dataclasses.replace(ctx, gms=gms)
    assert np.count_nonzero((ctx.resting[1:] == 0.0) & (ctx.resting[:-1] == 1.0)) >= 10
    stream = dwell_time.RaisedLimits(gms, tau, reach, 1 / reach, keep)  # the column's scale
    expected = np.array([
        stream.step(xi, vi, ri, di, ui)
        for xi, vi, ri, di, ui in zip(x, v, ctx.resting, ctx.dwell_s, ctx.direction, strict=True)
    ])  # fmt: skip
    assert np.count_nonzero(expected) > 20
    shape = {"tau_s": tau, "reach": reach, "kept_through_turns": keep}
    for _ in range(2):  # the second from the held elements kept in the context
        column = fx.DwellTime.basis(ctx, shape)[:, 0]
        np.testing.assert_array_equal(column, expected)
    assert dwell_time.HELD_KEY in ctx.derived


def test_a_gain_kept_through_turns_outlasts_the_turn_s() -> None:
    """On the path's strokes and jiggles the widest element often turns back before it
    slips: the spec's form keeps its raised force on after the turn where the other
    drops it, so the kept column is nonzero on more rows, and equal to it up to the
    first turn after the first start."""
    t, x, v = _path()
    delta = np.array([0.5e-6, 2e-6, 8e-6, 40e-6])
    w = np.array([1.0, 2.0, 1.5, 0.7])
    ctx = dataclasses.replace(fx.Context.along(t, x, v, 0 * t, 0 * t, 1e-5, 5e-9, 7.5e-9),
                              gms=GmsParams(w / delta, w))  # fmt: skip
    cols = [fx.DwellTime.basis(ctx, {"tau_s": 0.1, "reach": 0.3, "kept_through_turns": k})[:, 0]
            for k in (0.0, 1.0)]  # fmt: skip
    turned, kept = (np.count_nonzero(c) for c in cols)
    assert kept > 1.5 * turned > 0
    first = int(np.flatnonzero(cols[0] != cols[1])[0])
    assert np.any(cols[0][:first] != 0.0)
    assert cols[0][first] == 0.0 != cols[1][first]  # dropped at the turn, kept on


def test_under_the_play_law_the_held_elements_are_the_gms_kernel_s() -> None:
    """With the limit following the level, an element held since a start (it slips at
    level W) is the GMS kernel's play element: the held forces kept at every start are
    the kernel's element forces (``simulate_elements``) just before it. The path tells
    the laws apart: the seed law's held forces are not the play kernel's (C_v 1.2)."""
    t, x, v = _path()
    delta = np.array([0.5e-6, 2e-6, 8e-6, 40e-6])
    w = np.array([1.0, 2.0, 1.5, 0.7])
    for law in (True, False):
        gms = GmsParams(w / delta, w, slip_level=1.2, transition_velocity_m_s=2e-4,
                        limit_follows_level=law)  # fmt: skip
        ctx = dataclasses.replace(fx.Context.along(t, x, v, 0 * t, 0 * t, 1e-5, 5e-9, 7.5e-9),
                                  gms=gms)  # fmt: skip
        raised = dwell_time.RaisedLimits(gms, 0.1, 0.3)
        held = raised.held_at_starts(ctx)
        resting, dwell = ctx.resting, ctx.dwell_s
        starts = [j for j in range(1, x.size) if resting[j] == 0.0 and resting[j - 1] == 1.0
                  and dwell[j] >= REST_HOLD_S]  # fmt: skip
        assert len(starts) == held.shape[0] >= 10
        sub = GmsParams(raised.k, raised.w, slip_level=1.2, transition_velocity_m_s=2e-4,
                        limit_follows_level=True)  # fmt: skip
        kernel = simulate_elements(sub, x, v)[np.array(starts) - 1]
        if law:
            np.testing.assert_allclose(held, kernel, rtol=1e-9, atol=1e-12)
        else:
            assert np.max(np.abs(held - kernel)) > 1e-3  # N (5.8e-3 on this path)
