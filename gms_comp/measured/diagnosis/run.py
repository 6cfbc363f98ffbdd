"""The diagnosis as a pipeline: each stage takes one record and returns the next.

::

    Trace --prepare--> Prepared --fit_baseline--> Baseline --select--> Selection
          --refit--> Extended --residual_structure--> Structure --> Diagnosis

1. :mod:`.prepare`: kinematics, training and held-out rows, unusable traces refused.
2. :mod:`.baseline`: the free NNLS GMS with the seed's slip level C_v (or a calibrated
   GMS table), fitted on the training rows; its residual by motion phase (:mod:`.phases`).
3. :mod:`.candidates` and :mod:`.selection`: every catalogue effect fitted as
   extra design columns over its shape grid, kept by held-out error with a margin.
4. :mod:`.refit`: the kept effects refitted jointly, the extended model simulated.
5. :mod:`.structure`: ``unknown`` when the extended model's residual still has
   structure; :mod:`.coverage`: what the trace's motion cannot tell apart among the
   effects kept; :mod:`.result`: the record and its JSON.

Held-out samples are every third of ``n_blocks`` contiguous blocks of the trace (so
both parts hold every kind of motion), or a whole second trace when one is given.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable

from threadpoolctl import threadpool_limits

from gms_comp.arrays import FloatArray
from gms_comp.gms import GmsParams
from gms_comp.measured.diagnosis.baseline import Baseline, fit_baseline, held_residual, placed_on
from gms_comp.measured.diagnosis.candidates import Scorer, describe_trials
from gms_comp.measured.diagnosis.config import DiagnosisConfig, load_diagnosis_config
from gms_comp.measured.diagnosis.coverage import at_bound, caveats
from gms_comp.measured.diagnosis.criterion import lowers
from gms_comp.measured.diagnosis.design import rms
from gms_comp.measured.diagnosis.detection import detection_limits
from gms_comp.measured.diagnosis.intervals import intervals
from gms_comp.measured.diagnosis.level import extended_force
from gms_comp.measured.diagnosis.phases import phase_masks, residual_by_phase
from gms_comp.measured.diagnosis.prepare import Prepared, encoder_force_ratio, prepare
from gms_comp.measured.diagnosis.refit import Extended, refit
from gms_comp.measured.diagnosis.result import Diagnosis, verdict
from gms_comp.measured.diagnosis.selection import Selection, select
from gms_comp.measured.diagnosis.structure import residual_structure
from gms_comp.measured.policies import policy
from gms_comp.measured.traces import ForceKind, Trace
from gms_comp.tables.table import EXTENSION_CONTEXT_KEYS

__all__ = ["Diagnosis", "DiagnosisConfig", "diagnose", "load_diagnosis_config"]

Progress = Callable[[str], None]


def diagnose(
    trace: Trace,
    force_kind: ForceKind = "friction",
    validation: Trace | None = None,
    config: DiagnosisConfig | None = None,
    table: GmsParams | None = None,
    progress: Progress | None = None,
) -> Diagnosis:
    """Diagnose ``trace`` (see the module docstring).

    Parameters
    ----------
    trace
        The measured trace.
    force_kind
        ``friction`` (a test stand's sensor) or ``drive`` (inertia included).
    validation
        A held-out trace (else blocks of ``trace`` are held out).
    config
        The ``[diagnosis]`` settings.
    table
        A GMS table to calibrate as the baseline (else the free NNLS GMS).
    progress
        Called with a short message at each step (for a progress bar).
    """
    # the designs are tall and narrow: BLAS threads only fight over a shared machine's
    # cores (9 s against 2 s for 20 000 samples with another job running)
    with threadpool_limits(limits=1):
        return _diagnose(trace, force_kind, validation, config or DiagnosisConfig(), table,
                         progress)  # fmt: skip


def _reads_better(
    cfg: DiagnosisConfig, counts: Baseline, read: Baseline, selection: Selection
) -> bool:
    """Whether the counts read as motion (``read``) hold out better than the counts
    (``counts``, the baseline ``selection`` ran on) once the first effect it kept is in
    both designs: by the margin, or by the small margin and significantly, as an effect
    is kept (:func:`.gain.lowers`). An effect far above the noise hides what the counts
    cost the GMS: on offset-119 of the independent generator (a 27 nm encoder, a 1.1 N
    offset on a 4.4 N level, noise 0.037 N) the baselines held out 1.0235 and 1.0176 N
    (0.6 % apart); with the offset in both, 0.0409 and 0.0383 N (6.5 %, z 8), and on the
    counts a 104 Hz sensor_lowpass had been kept second to smooth their steps."""
    if not selection.chosen:
        return False
    first = list(selection.chosen[:1])
    rules = cfg.selection
    before = Scorer(counts.parts, first, rules).held_residual_N
    return lowers(rules, before, Scorer(read.parts, first, rules).held_residual_N)


def _along_every_sample(
    baseline: Baseline, extended: Extended
) -> tuple[Baseline, tuple[FloatArray, ...]]:
    """The baseline (its basis and coefficients) and the extended model along every
    sample of the trace, when it was fitted on every k-th (``fit_rate_Hz``); else as
    fitted. A feature crossed once holds few samples: picked, a bump's bins fell below
    what the structure reads (``prepare.MAX_FITTED_EVERY``)."""
    full = baseline.prepared.every_sample
    if full is None:
        return baseline, extended.predictions
    along = placed_on(full, baseline)
    return along, tuple(extended_force(fp, extended.gms, extended.extensions) for fp in along.parts)


def _diagnose(
    trace: Trace, force_kind: ForceKind, validation: Trace | None, cfg: DiagnosisConfig,
    table: GmsParams | None, progress: Progress | None,
) -> Diagnosis:  # fmt: skip
    start = time.perf_counter()
    say = progress or (lambda _msg: None)
    say("preparing the trace")
    prepared = prepare(trace, force_kind, validation, cfg)
    say("fitting the baseline")
    baseline = fit_baseline(prepared, cfg, table)
    # counts that show in the GMS driven by them: read as motion, if that fits better
    ratio = encoder_force_ratio(baseline.gms, prepared)
    info: dict[str, float] = {"encoder_noise_ratio": ratio, "fitted_every": prepared.fitted_every}
    as_motion: tuple[Prepared, Baseline] | None = None  # the reading not taken (yet)
    if ratio >= cfg.encoder_noise_ratio and prepared.encoder_step_m > 0.0:
        say("reading the encoder's counts as motion")
        # on the rows the counts hold out, so that the two readings compare like for like
        same = None if validation is not None else (prepared.every_sample or prepared).main.held
        read = prepare(trace, force_kind, validation, cfg, dequantise=True, held=same)
        again = fit_baseline(read, cfg, table)
        info["counts_heldout_rms_N"] = baseline.heldout_rms_N
        if again.heldout_rms_N < (1.0 - cfg.selection.margin) * baseline.heldout_rms_N:
            prepared, baseline = read, again
        else:
            as_motion = read, again
    baseline.info.update(info)
    # the first round alone decides the reading: the rest is selected on one of them only
    selection = select(baseline, dataclasses.replace(cfg, max_effects=1), say)
    if as_motion is not None and _reads_better(cfg, baseline, as_motion[1], selection):
        say("reading the encoder's counts as motion, judged with the first effect kept")
        prepared, baseline = as_motion
        baseline.info.update(info)
        selection = select(baseline, cfg, say)
    elif selection.chosen and cfg.max_effects > 1:
        selection = select(baseline, cfg, say, start=selection)
    say("joint refit")
    extended = refit(selection, cfg)
    say("residual structure")
    # judged (and shown) on every sample, when fitted on every k-th
    judged, predictions = _along_every_sample(baseline, extended)
    structure = residual_structure(
        judged.parts, predictions, judged.presliding_m, judged.sliding_force_N,
        prepared.noise_N, cfg.structure,
    )  # fmt: skip
    main = judged.parts[0]
    residual = main.part.force_N - judged.predictions[0]
    series = {
        "time_s": main.part.kin.time_s,
        "position_m": main.part.kin.position_m,
        "velocity_m_s": main.part.kin.velocity_m_s,
        "force_N": main.part.force_N,
        "baseline_N": judged.predictions[0],
        "extended_N": predictions[0],
    }
    if len(judged.parts) > 1:
        series.update(
            validation_force_N=judged.parts[1].part.force_N,
            validation_baseline_N=judged.predictions[1],
            validation_extended_N=predictions[1],
        )
    named = [c.effect.name for c in extended.ranked]
    design_rms, first = selection.first_round
    near = design_rms, [(t.option.effect.name, t.heldout_rms_N) for t in first]
    bounded = at_bound(
        [c.effect for c in extended.ranked], main.ctx, judged.presliding_m, cfg.caveats.at_bound
    )
    return Diagnosis(
        effect=verdict(extended.ranked, structure),
        ranked=extended.ranked,
        baseline_rms_N=judged.heldout_rms_N,
        extended_rms_N=rms(held_residual(judged.parts, predictions)),
        baseline=judged.to_json(),
        phases=residual_by_phase(residual, phase_masks(main.ctx, judged.presliding_m)),
        base_gms=baseline.gms,
        gms=extended.gms,
        extensions=extended.extensions,
        structure=structure,
        tried=describe_trials(selection.last_round, baseline.heldout_rms_N),
        series=series,
        seconds=time.perf_counter() - start,
        # the table's keys are Prepared's fields of the same names
        extension_context={key: getattr(prepared, key) for key in EXTENSION_CONTEXT_KEYS},
        in_context=tuple(policy(c.effect).in_context(c.effect, main.ctx) for c in extended.ranked),
        intervals=intervals(extended, prepared.noise_N, cfg),
        limits=detection_limits(
            extended.parts,
            extended.chosen,
            prepared.force_kind,
            baseline.sliding_force_N,
            baseline.presliding_m,
            prepared.noise_N,
            cfg,
        ),
        caveats=caveats(
            main.part.kin.velocity_m_s,
            prepared.standstill_speed_m_s,
            named,
            cfg.caveats,
            near,
            bounded,
            prepared.force_kind,
        ),
    )
