"""Stage 5, with a filter kept (a sensor low-pass): the free baseline fitted through it.

The blind baseline is fitted before any effect is known. Where the force sensor low-pass
filters the force, its elements bend to the filter's lag (the fit moves limits to long
break-aways, whose slow build-up looks like a lagging force). On sensor_lowpass-142 of
the independent generator (8.5 Hz, order 3, noise 0.15 N, presliding sines at 1.2 Hz)
the true filter held out 0.82 N on the blind elements and 0.158 N on elements fitted to
the same trace without the filter; the residual left a 0.87 N tone and read as
``unknown``.

Once the selection has kept a filter, the elements' knots (:func:`~.baseline.refine_knots`),
slip level and limits are fitted again with their columns through it, and kept if the
kept effects then fit the held-out rows better. On the test's trace the knots alone, the
level left as it was, held out no better than the blind elements' 1.27 N; with the level,
0.708 N for a noise of 0.699 N.

The elements are fitted on the measured force, with a kept additive effect still in it
(a ripple the refit placed the elements without, a Stribeck fall the level was chosen
with); the held-out comparison decides. The search's viscous and offset columns are not
passed through the filter (an offset passes it unchanged; both are dropped after the
search).
"""

from __future__ import annotations

import dataclasses
import functools

from gms_comp.arrays import FloatArray
from gms_comp.measured.diagnosis.baseline import (
    Baseline,
    _baseline,
    _fit,
    fit_free,
    refine_knots,
)
from gms_comp.measured.diagnosis.basis import FreeBasis, Sensor
from gms_comp.measured.diagnosis.candidates import Option, Scorer, through
from gms_comp.measured.diagnosis.config import SelectionConfig
from gms_comp.measured.diagnosis.prepare import Prepared


def fitted_through(
    prepared: Prepared, basis: FreeBasis, sensed: Sensor
) -> tuple[FreeBasis, FloatArray]:
    """``basis`` with its knots and slip level (from its own, :func:`~.baseline.fit_free`)
    fitted again with its columns through ``sensed``, and the coefficients fitted through
    it on them; the basis returned without ``sensed`` (the design applies the kept
    filters to every column)."""
    start = dataclasses.replace(basis, sensed=sensed)
    _, theta, _ = _fit(prepared, start, nuisance=True)
    start = refine_knots(prepared, start, theta)
    moved = fit_free(prepared, start.breakaway_m, start=start)
    _, theta, _ = _fit(prepared, moved)
    return dataclasses.replace(moved, sensed=None), theta


def sensed_again(baseline: Baseline, chosen: list[Option], rules: SelectionConfig) -> Baseline:
    """``baseline`` with its elements fitted again through ``chosen``'s filters
    (:func:`fitted_through`) if ``chosen`` then fits the held-out rows better; else
    ``baseline`` (also without a filter kept, or with a table baseline)."""
    filters = [o for o in chosen if o.is_filter]
    if not filters or not isinstance(baseline.basis, FreeBasis):
        return baseline
    sensed = functools.partial(through, filters)
    basis, theta = fitted_through(baseline.prepared, baseline.basis, sensed)
    info = {**baseline.info, "fitted_through": [o.effect.name for o in filters]}
    trial = _baseline(baseline.prepared, basis, theta, info)
    if (
        Scorer(trial.parts, chosen, rules).heldout_rms_N
        < Scorer(baseline.parts, chosen, rules).heldout_rms_N
    ):
        return trial
    return baseline
