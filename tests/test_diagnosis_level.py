"""The blind baseline's velocity level against an independent truth.

The independent generator (tests/indepgen.py) raises its element limits from the stick
level to C_v as 1 + (C_v - 1) q / (1 + q), q = (|v| / v_t)^2: still 10 % short of C_v at
3 v_t, 1 % at 10 v_t. A Gaussian onset (the seed's default shape) reaches C_v within a
per cent by 2.1 v_t, so a baseline held to it is low over a decade of speed above v_t,
and a viscous term took that on effect-free traces."""

from __future__ import annotations

import functools
import itertools
import math

import numpy as np
import pytest
from indepgen import make_trace

from gms_comp.gms import GmsParams, simulate
from gms_comp.measured.diagnosis import baseline as baseline_module
from gms_comp.measured.diagnosis import slip_level
from gms_comp.measured.diagnosis.baseline import Baseline, fit_baseline
from gms_comp.measured.diagnosis.config import DiagnosisConfig
from gms_comp.measured.diagnosis.prepare import prepare
from gms_comp.measured.traces import Trace


@functools.cache
def _baseline(seed: int) -> tuple[Baseline, float, float, float]:
    gen = make_trace("none", seed)
    trace = Trace("indep", gen.time_s, gen.position_m, gen.force_N)
    baseline = fit_baseline(prepare(trace, "friction", None, DiagnosisConfig()), DiagnosisConfig(),
                            None)  # fmt: skip
    return baseline, gen.transition_velocity_m_per_s, gen.noise_N, gen.C_v


@pytest.mark.parametrize("seed", [114, 105])
def test_the_level_follows_a_slow_approach_to_the_sliding_level(seed: int) -> None:
    """Above the truth's v_t the held-out residual's mean in every speed band (by
    direction) is within a third of the noise; held to the Gaussian shape it was 0.5-0.7 x
    the noise on seed 114 (0.2-0.27 N at 3-30 mm/s). And the fitted level is the truth's
    within 1.5 % from 3 v_t to 30 v_t (the shape, not only the residual)."""
    baseline, v_t, noise, c_v = _baseline(seed)
    part = baseline.parts[0].part
    residual = part.force_N - baseline.predictions[0]
    v = part.kin.velocity_m_s
    top = float(np.max(np.abs(v)))
    edges = np.geomspace(3 * v_t, top, 6)
    for lo, hi in itertools.pairwise(edges):
        for sign in (1.0, -1.0):
            band = part.held & (sign * v > lo) & (sign * v <= hi)
            if np.count_nonzero(band) < 200:
                continue
            assert abs(float(np.mean(residual[band]))) < noise / 3, (lo, hi, sign)
    speeds = np.geomspace(3 * v_t, 30 * v_t, 50)
    q = (speeds / v_t) ** 2
    truth = 1.0 + (c_v - 1.0) * q / (1.0 + q)
    np.testing.assert_allclose(baseline.gms.level(speeds), truth, rtol=0.015)


def test_the_search_can_take_the_rational_tail(monkeypatch: pytest.MonkeyPatch) -> None:
    """With the rational tail among the searched ones (slip_level.TAILS; not by default,
    see there), the baseline of a trace whose level rises as 1 + (C_v - 1) q / (1 + q)
    takes it, and its level is the truth's within 1 % from v_t / 3 to 30 v_t (seed 131:
    C_v 1.2413 for 1.2418, at most 0.63 % off)."""
    tails = (math.inf, slip_level.RATIONAL_TAIL)
    monkeypatch.setattr(slip_level, "TAILS", tails)
    monkeypatch.setattr(baseline_module, "TAILS", tails)
    gen = make_trace("none", 131)
    trace = Trace("indep", gen.time_s, gen.position_m, gen.force_N)
    cfg = DiagnosisConfig()
    fitted = fit_baseline(prepare(trace, "friction", None, cfg), cfg, None)
    assert fitted.gms.transition_tail == slip_level.RATIONAL_TAIL
    v_t = gen.transition_velocity_m_per_s
    speeds = np.geomspace(v_t / 3, 30 * v_t, 50)
    q = (speeds / v_t) ** 2
    truth = 1.0 + (gen.C_v - 1.0) * q / (1.0 + q)
    np.testing.assert_allclose(fitted.gms.level(speeds), truth, rtol=0.01)


@pytest.mark.parametrize("law", [True, False])
def test_the_search_takes_the_law_a_trace_was_made_with(law: bool) -> None:
    """The independent generator's elements are springs clipped at s(v) W_i (its own
    play operator): the baseline takes ``limit_follows_level``. The same path through the
    seed's law (our kernel, six elements, the generator's C_v, v_t and noise) gives the
    seed's law; either way its C_v is the truth's within 1 % (seed 131: 1.2344 with the
    play law, 1.2414 with the seed's, for 1.2418)."""
    gen = make_trace("none", 131)
    force = gen.force_N
    if not law:
        d = np.geomspace(1e-6, 3e-5, 6)
        w = np.full(6, gen.sliding_force_N / gen.C_v / 6)
        seed_law = GmsParams(w / d, w, slip_level=gen.C_v,
                             transition_velocity_m_s=gen.transition_velocity_m_per_s)  # fmt: skip
        v = np.gradient(gen.position_m, gen.time_s)
        noise = np.random.default_rng(131).normal(0.0, gen.noise_N, v.size)
        force = simulate(seed_law, gen.position_m, v)[0] + noise
    cfg = DiagnosisConfig()
    trace = Trace("indep", gen.time_s, gen.position_m, force)
    fitted = fit_baseline(prepare(trace, "friction", None, cfg), cfg, None)
    assert fitted.gms.limit_follows_level is law
    assert fitted.gms.slip_level == pytest.approx(gen.C_v, rel=0.01)
