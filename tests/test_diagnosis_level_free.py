"""Stribeck scored with the slip level free (diagnosis.level_free), against an
independent truth (tests/indepgen.py).

stribeck-120 holds C_v 1.14 reached over 0.35 mm/s and a Stribeck fall of ratio 1.24 at
6.4 mm/s: the level rises from stick, then falls towards sliding speed. The GMS alone
fits best at C_v 1, where a Stribeck column cannot raise the level at low speed above
the stick level; refitted at the truth's level it can."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from indepgen import Generated, make_trace

from gms_comp.measured.diagnosis.baseline import Baseline, fit_baseline
from gms_comp.measured.diagnosis.basis import FreeBasis
from gms_comp.measured.diagnosis.candidates import Option, Scorer
from gms_comp.measured.diagnosis.config import DiagnosisConfig
from gms_comp.measured.diagnosis.level import with_free_level
from gms_comp.measured.diagnosis.prepare import prepare
from gms_comp.measured.traces import Trace
from gms_comp.runtime import effects as fx


@functools.cache
def _fitted(case: str, seed: int) -> tuple[Generated, Baseline]:
    gen = make_trace(case, seed)
    trace = Trace("indep", gen.time_s, gen.position_m, gen.force_N)
    cfg = DiagnosisConfig()
    return gen, fit_baseline(prepare(trace, "friction", None, cfg), cfg, None)


def test_a_stribeck_fall_is_found_at_the_level_it_rises_from() -> None:
    gen, baseline = _fitted("stribeck", 120)
    (name, truth), *_ = gen.effects
    assert name == "stribeck"
    free = with_free_level(fx.Stribeck, baseline, Scorer(baseline.parts, []))
    assert free is not None
    # the level the fall sits on: the truth's C_v within the grid's spacing
    assert isinstance(free.baseline.basis, FreeBasis)
    assert free.baseline.basis.slip_level == pytest.approx(gen.C_v, abs=0.1)
    assert free.trial.heldout_rms_N < 0.6 * baseline.heldout_rms_N
    # the grid's ratio before any refinement: within the benchmark's tolerance
    ratio = 1.0 + float(free.trial.theta[-1])
    assert ratio - 1.0 == pytest.approx(truth["ratio"] - 1.0, rel=0.3)


def test_nothing_is_searched_where_the_baseline_leaves_noise() -> None:
    gen, baseline = _fitted("none", 101)
    assert baseline.heldout_rms_N < 1.2 * gen.noise_N  # the premise: the GMS explains it
    assert with_free_level(fx.Stribeck, baseline, Scorer(baseline.parts, [])) is None


@pytest.mark.slow  # a baseline and 17 levels on a 120 000-sample trace (40 s)
def test_a_stribeck_fall_after_an_offset_is_found_on_the_force_fitted_beside_it() -> None:
    # pair_offset_stribeck-259: an offset of 30 % of the level, then a fall of ratio 1.15
    # over 3.4 mm/s on C_v 1.10. The baseline fitted alone carries part of the offset in
    # its limits; the level's GMS force refitted beside the offset kept, the fall on it
    # holds out at the noise (0.958 N for a noise of 0.957 N; on the baseline's own GMS
    # force, 0.988 N)
    gen, fitted = _fitted("pair_offset_stribeck", 259)
    truth = dict(gen.effects)["stribeck"]
    offset = Option(fx.Offset, {})
    free = with_free_level(fx.Stribeck, fitted, Scorer(fitted.parts, [offset]))
    assert free is not None
    assert isinstance(free.baseline.basis, FreeBasis)
    assert free.baseline.basis.slip_level == pytest.approx(gen.C_v, abs=0.1)
    above = np.sqrt(max(free.trial.heldout_rms_N**2 - gen.noise_N**2, 0.0))
    assert above < 0.15 * gen.noise_N  # 0.26 x on the baseline's own GMS force
    ratio = 1.0 + float(free.trial.theta[-1])
    assert ratio - 1.0 == pytest.approx(truth["ratio"] - 1.0, rel=0.3)
