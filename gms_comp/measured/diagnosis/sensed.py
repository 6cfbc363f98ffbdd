"""Stage 5, with a sensor low-pass kept: the free baseline fitted again through it.

The blind baseline is fitted before any effect is known. Where the force sensor low-pass
filters the force, its elements bend to the filter's lag (the fit moves limits to long
break-aways, whose slow build-up looks like a lagging force). Once the selection has kept
a filter, the elements' knots and slip level are fitted again with their columns through
it, and kept if the kept effects then fit the held-out rows better. On sensor_lowpass-142
of the independent generator (8.5 Hz, order 3, noise 0.15 N, presliding sines at
1.2 Hz) the true filter held out 0.82 N on the blind elements and 0.158 N on elements
fitted to the same trace without the filter; the residual left a 0.87 N tone and read
as ``unknown``.
"""

from __future__ import annotations

import dataclasses

from gms_comp.arrays import FloatArray
from gms_comp.measured.diagnosis.baseline import (
    Baseline,
    _fit,
    fit_free,
    fitted_on,
    refine_knots,
)
from gms_comp.measured.diagnosis.basis import FreeBasis, Sensor
from gms_comp.measured.diagnosis.candidates import Option, Scorer
from gms_comp.measured.diagnosis.prepare import Prepared


def fitted_through(prepared: Prepared, basis: FreeBasis, sensed: Sensor) -> FreeBasis:
    """``basis`` fitted again with its columns through ``sensed``: its knots
    (:func:`~.baseline.refine_knots`) and slip level (:func:`~.baseline.fit_free` from its
    own); returned without ``sensed``, which the design applies to every column."""
    start = dataclasses.replace(basis, sensed=sensed)
    _, theta, _ = _fit(prepared, start, nuisance=True)
    start = refine_knots(prepared, start, theta)
    return dataclasses.replace(fit_free(prepared, start.breakaway_m, start=start), sensed=None)


def sensed_again(baseline: Baseline, chosen: list[Option]) -> Baseline:
    """``baseline`` fitted again through ``chosen``'s filters (:func:`fitted_through`)
    if ``chosen`` then fits the held-out rows better; else ``baseline`` (also without a
    filter kept, or with a table baseline)."""
    filters = [o.filter_effect() for o in chosen if o.is_filter]
    if not filters or not isinstance(baseline.basis, FreeBasis):
        return baseline

    def sensed(values: FloatArray, sample_time_s: float) -> FloatArray:
        for f in filters:
            values = f.filter_columns(values, sample_time_s)
        return values

    basis = fitted_through(baseline.prepared, baseline.basis, sensed)
    trial = fitted_on(baseline.prepared, basis, baseline.info)
    if Scorer(trial.parts, chosen).heldout_rms_N < Scorer(baseline.parts, chosen).heldout_rms_N:
        return trial
    return baseline
