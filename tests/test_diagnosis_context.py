"""The diagnosis's path context against an independent truth: where a dwell gain acts.

The independent generator (tests/indepgen.py, tests/indepfriction.py) raises the element
limits at the first moving sample after a standstill, per the catalogue's text; its extra
force lives in the first micrometres of each break-away, mostly at speeds far below any
standstill speed a diagnosis could pick from the peak speed. The context the diagnosis
builds from the measured (quantised) positions must mark those samples as not resting and
date the dwell as the truth does, or no dwell column can see them.
"""

from __future__ import annotations

import numpy as np
import pytest
from indepfriction import friction
from indepgen import baseline, make_trace

from gms_comp.measured.diagnosis.config import DiagnosisConfig
from gms_comp.measured.diagnosis.prepare import prepare
from gms_comp.measured.traces import Trace
from gms_comp.runtime import effects as fx


def _context(seed: int, cfg: DiagnosisConfig) -> tuple[fx.Context, np.ndarray, np.ndarray]:
    gen = make_trace("dwell_time", seed)
    truth = baseline(seed)[0]
    extra = friction(truth, gen.effects) - friction(truth, ())
    trace = Trace("indep", gen.time_s, gen.position_m, gen.force_N)
    prepared = prepare(trace, "friction", None, cfg)
    kin = prepared.main.kin
    ctx = fx.Context.of(
        kin, np.zeros(len(trace)), prepared.standstill_speed_m_s,
        prepared.reversal_deadband_m, prepared.rest_band_m,
    )  # fmt: skip
    # the truth's dwell before each sample: the last standstill (v == 0) that ended
    moving = truth.velocity_m_s != 0.0
    starts = np.flatnonzero(moving[1:] & ~moving[:-1]) + 1
    stops = np.flatnonzero(~moving[1:] & moving[:-1]) + 1
    true_dwell = np.zeros(len(trace))
    for start in starts:
        before = stops[stops < start]
        if before.size:
            true_dwell[start:] = truth.time_s[start] - truth.time_s[before[-1]]
    return ctx, extra, true_dwell


# seed 103: after a rest of 0.97 s the truth creeps 2.5 um forward at up to 7 um/s (below
# any standstill speed) and turns back without stopping; the context dates that start's
# dwell from the creep's end (25 ms), the truth from the rest before it. With the dwell
# gains sized at 10-30 % of the level, the raised elements that did not slip in the creep
# put 16 % of the dwell force's energy there (83 % dated within 5 %).
CREEP = pytest.mark.xfail(strict=True, reason="a creep slower than the standstill speed")


@pytest.mark.parametrize("seed", [101, 102, pytest.param(103, marks=CREEP)])
def test_the_dwell_force_falls_where_the_context_is_moving_with_the_true_dwell(
    seed: int,
) -> None:
    ctx, extra, true_dwell = _context(seed, DiagnosisConfig())
    energy = extra**2
    seen = ctx.resting == 0.0
    assert energy[seen].sum() >= 0.95 * energy.sum()
    # dated as the truth dates it, energy-weighted: within 5 % or 5 ms (a quantised position
    # moves its last step before the truth stops, and leaves the band a few nanometres
    # after the truth starts; 5 % of t_d is at most 5 % of ln(1 + t_d / tau))
    acting = energy > 0
    close = np.abs(ctx.dwell_s - true_dwell) <= np.maximum(0.05 * true_dwell, 5e-3)
    assert energy[acting & close].sum() >= 0.95 * energy.sum()


def test_a_speed_threshold_alone_misses_the_dwell_force() -> None:
    # the rule before the rest band: resting until 1 % of the peak speed is exceeded
    ctx, extra, _ = _context(101, DiagnosisConfig(rest_band_steps=0.0))
    energy = extra**2
    assert energy[ctx.resting == 0.0].sum() < 0.3 * energy.sum()
