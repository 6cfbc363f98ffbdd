"""The selection resumed after its first round (the diagnosis runs the first round alone to
decide how the encoder's counts are read) is the selection run through."""

from __future__ import annotations

import dataclasses

import pytest
from indepgen import make_trace

from gms_comp.measured.diagnosis.baseline import fit_baseline
from gms_comp.measured.diagnosis.config import DiagnosisConfig
from gms_comp.measured.diagnosis.prepare import prepare
from gms_comp.measured.diagnosis.selection import select
from gms_comp.measured.traces import Trace


@pytest.mark.slow
def test_a_selection_stopped_and_resumed_is_the_selection_run_through() -> None:
    """The diagnosis runs the first round alone (it decides how the encoder's counts are
    read) and resumes from it: every round after must be what a selection run through
    makes of the same baseline, to the last digit (the level-free grid's baselines
    carried with it)."""
    gen = make_trace("pair_offset_stribeck", 121, 20_000)
    cfg = DiagnosisConfig()
    trace = Trace("indep", gen.time_s, gen.position_m, gen.force_N)
    baseline = fit_baseline(prepare(trace, "friction", None, cfg), cfg, None)
    through = select(baseline, cfg)
    assert len(through.chosen) >= 2  # the premise: rounds after the first are resumed
    stopped = select(baseline, dataclasses.replace(cfg, max_effects=1))
    assert stopped.chosen == through.chosen[:1]
    resumed = select(baseline, cfg, start=stopped)
    assert resumed.chosen == through.chosen
    assert resumed.heldout_rms_N == through.heldout_rms_N
    assert resumed.baseline is through.baseline or (
        resumed.baseline.heldout_rms_N == through.baseline.heldout_rms_N
    )
    assert [t.heldout_rms_N for t in resumed.last_round] == [
        t.heldout_rms_N for t in through.last_round
    ]
    assert resumed.first_round[0] == through.first_round[0]
