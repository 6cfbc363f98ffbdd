"""A fast trace is fitted on every k-th sample, its kinematics from every sample, and the
model fitted is judged on every sample."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest
from indepgen import Generated, baseline, make_trace

from gms_comp.app.commands.diagnose import _every
from gms_comp.measured.diagnosis.baseline import fit_baseline, placed_on
from gms_comp.measured.diagnosis.candidates import Scorer
from gms_comp.measured.diagnosis.config import DiagnosisConfig
from gms_comp.measured.diagnosis.prepare import prepare
from gms_comp.measured.diagnosis.run import diagnose
from gms_comp.measured.traces import Trace

SEED = 247  # the independent generator draws 4.1 kHz for it
FAST = DiagnosisConfig(fit_rate_Hz=600.0)
MAX_FITTED_EVERY = FAST.split.max_fitted_every


@functools.cache
def _generated() -> Generated:
    return make_trace("none", SEED)  # 131 199 samples


@functools.cache
def _trace() -> tuple[Trace, float]:
    gen = _generated()
    return Trace("none-247", gen.time_s, gen.position_m, gen.force_N), gen.sample_rate_Hz


def test_a_fast_trace_keeps_every_kth_sample_and_the_full_rate_acceleration() -> None:
    trace, rate = _trace()
    assert rate > 3000.0
    every = int(rate // 600.0)
    assert every > MAX_FITTED_EVERY  # 4.1 kHz: every 6th, but at most every 2nd
    every = MAX_FITTED_EVERY
    prepared = prepare(trace, "friction", None, FAST)
    fitted = prepared.main
    full = prepare(trace, "friction", None, DiagnosisConfig(fit_rate_Hz=0.0)).main
    assert prepared.fitted_every == every
    assert "1 in 2 fitted" in _every({"fitted_every": prepared.fitted_every})
    assert len(full.kin) == len(trace)
    assert len(fitted.kin) == len(range(0, len(trace), every))
    assert np.array_equal(fitted.kin.time_s, trace.time_s[::every])
    assert np.array_equal(fitted.force_N, trace.force_N[::every])
    assert np.array_equal(fitted.path_position_m, trace.position_m[::every])
    # the kinematics are the full rate's, picked: not differenced again at the lower rate
    assert np.array_equal(fitted.kin.acceleration_m_s2, full.kin.acceleration_m_s2[::every])
    assert np.array_equal(fitted.kin.velocity_m_s, full.kin.velocity_m_s[::every])
    # and they follow the generator's own acceleration (an independent truth) in size
    truth = baseline(SEED)[0].acceleration_m_s2[::every]
    moving = np.abs(truth) > 0.1 * np.max(np.abs(truth))
    ratio = np.sqrt(
        np.mean(fitted.kin.acceleration_m_s2[moving] ** 2) / np.mean(truth[moving] ** 2)
    )
    assert ratio == pytest.approx(1.0, abs=0.05)
    # a third of the blocks still held out
    assert np.mean(fitted.held) == pytest.approx(np.mean(full.held), abs=0.02)


def test_a_trace_below_twice_the_rate_keeps_every_sample() -> None:
    trace, _ = _trace()
    slow = dataclasses.replace(trace, time_s=trace.time_s[0] + np.arange(len(trace)) / 1190.0)
    part = prepare(slow, "friction", None, FAST).main
    assert len(part.kin) == len(slow)


def test_exactly_twice_the_rate_takes_every_other_sample() -> None:
    trace, _ = _trace()
    even = dataclasses.replace(trace, time_s=np.arange(len(trace)) / 1200.0)
    part = prepare(even, "friction", None, FAST).main
    assert np.array_equal(part.kin.time_s, even.time_s[::2])


def test_the_held_rows_of_another_reading_apply_to_the_fitted_rows() -> None:
    # the encoder's counts read as motion are compared on the first reading's held rows,
    # given at every sample
    trace, _ = _trace()
    cfg = FAST
    first = prepare(trace, "friction", None, cfg)
    assert first.every_sample is not None
    every = first.every_sample.main
    assert len(every.kin) == len(trace) and every.kin is not first.main.kin
    assert np.array_equal(every.held[::MAX_FITTED_EVERY], first.main.held)
    read = prepare(trace, "friction", None, cfg, dequantise=True, held=every.held)
    assert np.array_equal(read.main.held, first.main.held)
    assert np.array_equal(read.main.kin.time_s, first.main.kin.time_s)


def test_a_fast_trace_is_fitted_on_every_2nd_sample_by_default() -> None:
    trace, _ = _trace()
    assert DiagnosisConfig().fit_rate_Hz > 0.0
    prepared = prepare(trace, "friction", None, DiagnosisConfig())
    assert prepared.fitted_every == MAX_FITTED_EVERY
    assert prepare(trace, "friction", None, DiagnosisConfig(fit_rate_Hz=0.0)).every_sample is None


def test_the_model_fitted_on_every_2nd_sample_is_judged_and_shown_on_every_sample() -> None:
    trace, _ = _trace()
    gen = _generated()
    result = diagnose(trace, "friction", config=FAST)
    assert result.baseline["fitted_every"] == MAX_FITTED_EVERY
    series = result.series
    assert np.array_equal(series["time_s"], trace.time_s)
    assert np.array_equal(series["force_N"], trace.force_N)
    # the models along every sample leave the generator's own noise, no more (a model
    # placed wrong between the fitted samples would leave its misfit on the others)
    for key in ("baseline_N", "extended_N"):
        left = trace.force_N - series[key]
        assert np.sqrt(np.mean(left[1::2] ** 2)) == pytest.approx(gen.noise_N, rel=0.1)
        assert np.sqrt(np.mean(left[::2] ** 2)) == pytest.approx(gen.noise_N, rel=0.1)
    assert result.structure.noise_rms_N == pytest.approx(gen.noise_N, rel=0.05)
    assert result.extended_rms_N == pytest.approx(gen.noise_N, rel=0.1)


def test_a_dwell_gain_at_few_starts_is_judged_on_every_sample() -> None:
    # dwell_time-248 (3.6 kHz, a gain of 0.09 at 19 starts, noise 2.7 % of the level): on
    # every 2nd sample its local test read z 2.1-3.0 (threshold 3) and `none`; on every
    # sample z 5.7
    gen = make_trace("dwell_time", 248)
    trace = Trace("dwell_time-248", gen.time_s, gen.position_m, gen.force_N)
    prepared = prepare(trace, "friction", None, DiagnosisConfig())
    assert prepared.fitted_every == MAX_FITTED_EVERY and prepared.every_sample is not None
    result = diagnose(trace, "friction")
    assert result.effect == "dwell_time", result.ranked
    assert len(result.series["time_s"]) == len(trace)


def test_the_judge_of_a_picked_design_is_the_same_design_on_every_sample() -> None:
    trace, _ = _trace()
    prepared = prepare(trace, "friction", None, FAST)
    fitted = fit_baseline(prepared, FAST, None)
    every = prepared.every_sample
    assert every is not None
    scorer = Scorer(fitted.parts, [], FAST.selection, lambda: placed_on(every, fitted).parts)
    judge = scorer.judge
    assert judge is not scorer
    alone = Scorer(
        fitted.parts, [], FAST.selection
    )  # no parts of every sample: judged where fitted
    assert alone.judge is alone
    assert len(judge.parts[0].part.force_N) == len(trace)
    # the same coefficients fit both (a GMS is rate-independent; the held-out RMS the
    # noise's on either)
    assert judge.heldout_rms_N == pytest.approx(scorer.heldout_rms_N, rel=0.02)
    gap = judge.model()[::MAX_FITTED_EVERY] - scorer.model()
    assert np.sqrt(np.mean(gap**2)) < 0.2 * _generated().noise_N
