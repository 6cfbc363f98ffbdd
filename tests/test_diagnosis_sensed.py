"""The blind baseline fitted again through a kept sensor low-pass (diagnosis.sensed).

The trace is the independent generator's (tests/indepgen.py: its own play operator and
scipy's Butterworth filter on the force), not the diagnosis's kernel or filter."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from indepgen import make_trace
from scipy import signal

from gms_comp.kinematics import Kinematics
from gms_comp.measured.diagnosis.baseline import fit_baseline
from gms_comp.measured.diagnosis.basis import FreeBasis
from gms_comp.measured.diagnosis.candidates import Option, Scorer
from gms_comp.measured.diagnosis.config import DiagnosisConfig, SelectionConfig
from gms_comp.measured.diagnosis.prepare import prepare
from gms_comp.measured.diagnosis.refit import sensed_again
from gms_comp.measured.traces import Trace
from gms_comp.runtime import effects as fx

RULES = SelectionConfig()


def test_the_elements_fitted_through_a_kept_low_pass_fit_down_to_the_noise() -> None:
    # seed 142 at 40 000 samples: a third-order low-pass at 8.5 Hz on presliding sines;
    # the blind elements bend to its lag and leave 1.8 x the noise with the true filter
    gen = make_trace("sensor_lowpass", 142, samples=40_000)
    truth = dict(gen.effects)["sensor_lowpass"]
    cfg = DiagnosisConfig()
    trace = Trace("sensed", gen.time_s, gen.position_m, gen.force_N)
    blind = fit_baseline(prepare(trace, "friction", None, cfg), cfg, None)
    kept = [Option(fx.SensorLowpass, {"cutoff_Hz": truth["cutoff_Hz"], "order": truth["order"]})]
    again = sensed_again(blind, kept, RULES)
    assert Scorer(blind.parts, kept, RULES).heldout_rms_N > 1.5 * gen.noise_N
    assert Scorer(again.parts, kept, RULES).heldout_rms_N < 1.05 * gen.noise_N
    assert isinstance(again.basis, FreeBasis) and again.basis.sensed is None  # the design filters
    # without a filter kept nothing is fitted again
    assert sensed_again(blind, [Option(fx.Offset, {})], RULES) is blind


def test_a_sensed_basis_passes_its_element_columns_through_the_filter() -> None:
    rate = 1000.0
    t = np.arange(2000) / rate
    x = 50e-6 * np.sin(2 * np.pi * 3.0 * t)
    v = np.gradient(x, t)
    kin = Kinematics(t, x, v, np.gradient(v, t))
    sos = signal.butter(2, 20.0, fs=rate, output="sos")

    def sensed(values: np.ndarray, sample_time_s: float) -> np.ndarray:
        assert sample_time_s == pytest.approx(1.0 / rate)
        return np.asarray(signal.sosfilt(sos, values, axis=0))

    plain = FreeBasis(np.array([1e-6, 10e-6]))
    through = dataclasses.replace(plain, sensed=sensed)
    raw = plain.columns(kin, spare=1)
    out = through.columns(kin, spare=1)
    np.testing.assert_allclose(out[:, :2], signal.sosfilt(sos, raw[:, :2], axis=0))
    assert out.shape == raw.shape
