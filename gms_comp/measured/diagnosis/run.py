"""The diagnosis as a chain of stages, each taking one record and returning the next::

    Trace --read--> Baseline --select--> Selection --refit--> Extended --> Diagnosis

:func:`read` prepares the trace (:mod:`.prepare`) and fits its baseline (:mod:`.baseline`),
the encoder's counts read as motion where that fits better; :mod:`.selection` keeps effects
by the criterion; :mod:`.refit` refits them jointly, with the backward pass; the record
(:mod:`.result`) holds the structure left (:mod:`.structure`), the intervals, the
detection limits and the caveats (:mod:`.intervals`, :mod:`.detection`, :mod:`.coverage`).
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
from gms_comp.measured.diagnosis.intervals import intervals, tangents
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
    """Diagnose ``trace`` (see the module docstring): ``force_kind`` ``friction`` (a test
    stand's sensor) or ``drive`` (inertia included); ``validation`` a held-out trace (else
    blocks of ``trace`` are held out); ``config`` the ``[diagnosis]`` settings; ``table`` a
    GMS table to calibrate as the baseline (else the free NNLS GMS); ``progress`` called
    with a short message at each step."""
    # the designs are tall and narrow: BLAS threads only fight over a shared machine's cores
    with threadpool_limits(limits=1):
        cfg = config or DiagnosisConfig()
        start = time.perf_counter()
        say = progress or (lambda _msg: None)
        baseline, first = read(trace, force_kind, validation, cfg, table, say)
        selection = select(baseline, cfg, say, start=first)
        say("joint refit")
        extended = refit(selection, cfg)
        say("intervals and detection limits")
        return _record(selection, extended, cfg, time.perf_counter() - start)


def read(
    trace: Trace, force_kind: ForceKind, validation: Trace | None, cfg: DiagnosisConfig,
    table: GmsParams | None, say: Progress,
) -> tuple[Baseline, Selection | None]:  # fmt: skip
    """The trace prepared and its baseline, the position read as measured or (where a
    count of the encoder shows in the GMS driven by it, ``encoder_noise_ratio``) as the
    counts read as motion, whichever holds out better by the margin; where neither does,
    the two are compared again with the first effect the counts keep in both designs
    (an effect far above the noise hides what the counts cost the GMS). Returns the
    baseline and that first round (None: none was run on it)."""
    say("preparing the trace")
    prepared = prepare(trace, force_kind, validation, cfg)
    say("fitting the baseline")
    counts = fit_baseline(prepared, cfg, table)
    ratio = encoder_force_ratio(counts.gms, prepared)
    info = {"encoder_noise_ratio": ratio, "fitted_every": float(prepared.fitted_every)}
    if ratio < cfg.encoder_noise_ratio or prepared.encoder_step_m <= 0.0:
        return _with_info(counts, info), None
    say("reading the encoder's counts as motion")
    # on the rows the counts hold out, so that the two readings compare like for like
    same = None if validation is not None else (prepared.every_sample or prepared).main.held
    motion = fit_baseline(prepare(trace, force_kind, validation, cfg, True, same), cfg, table)
    info["counts_heldout_rms_N"] = counts.heldout_rms_N
    counts, motion = _with_info(counts, info), _with_info(motion, info)
    if motion.heldout_rms_N < (1.0 - cfg.selection.margin) * counts.heldout_rms_N:
        return motion, None
    first = select(counts, dataclasses.replace(cfg, max_effects=1), say)
    if first.chosen and _reads_better(cfg, counts, motion, first):
        say("reading the encoder's counts as motion, judged with the first effect kept")
        return motion, None
    return counts, first


def _with_info(baseline: Baseline, info: dict[str, float]) -> Baseline:
    return dataclasses.replace(baseline, info={**baseline.info, **info})


def _reads_better(
    cfg: DiagnosisConfig, counts: Baseline, motion: Baseline, first: Selection
) -> bool:
    """Whether the counts read as motion hold out better than the counts, the first effect
    kept on the counts in both designs, by the criterion (:func:`.criterion.lowers`)."""
    kept = list(first.chosen[:1])
    rules = cfg.selection
    before = Scorer(counts.parts, kept, rules).held_residual_N
    return lowers(rules, before, Scorer(motion.parts, kept, rules).held_residual_N)


def _along_every_sample(
    baseline: Baseline, extended: Extended
) -> tuple[Baseline, tuple[FloatArray, ...]]:
    """The baseline and the extended model along every sample of the trace, when it was
    fitted on every k-th (``fit_rate_Hz``); else as fitted: a feature crossed once holds
    few samples, and picked, a bump's bins fell below what the structure reads."""
    full = baseline.prepared.every_sample
    if full is None:
        return baseline, extended.predictions
    along = placed_on(full, baseline)
    return along, tuple(extended_force(fp, extended.gms, extended.extensions) for fp in along.parts)


def _record(
    selection: Selection, extended: Extended, cfg: DiagnosisConfig, seconds: float
) -> Diagnosis:
    """The structure left (on every sample), the intervals, the detection limits and the
    caveats, and the record of it all."""
    baseline = selection.baseline
    prepared: Prepared = baseline.prepared
    judged, predictions = _along_every_sample(baseline, extended)
    structure = residual_structure(
        judged.parts, predictions, judged.presliding_m, judged.sliding_force_N,
        prepared.noise_N, cfg.structure,
    )  # fmt: skip
    main = judged.parts[0]
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
    effects = [c.effect for c in extended.ranked]
    bounded = at_bound(effects, main.ctx, judged.presliding_m, cfg.caveats.at_bound)
    velocity = main.part.kin.velocity_m_s
    steps = tangents(extended)  # the baseline's level and knots, stepped
    return Diagnosis(
        effect=verdict(extended.ranked, structure),
        ranked=extended.ranked,
        baseline_rms_N=judged.heldout_rms_N,
        extended_rms_N=rms(held_residual(judged.parts, predictions)),
        baseline=judged.to_json(),
        phases=residual_by_phase(
            main.part.force_N - judged.predictions[0], phase_masks(main.ctx, judged.presliding_m)
        ),
        base_gms=baseline.gms,
        gms=extended.gms,
        extensions=extended.extensions,
        structure=structure,
        tried=describe_trials(selection.last_round, baseline.heldout_rms_N),
        series=series,
        seconds=seconds,
        # the table's keys are Prepared's fields of the same names
        extension_context={key: getattr(prepared, key) for key in EXTENSION_CONTEXT_KEYS},
        in_context=tuple(policy(e).in_context(e, main.ctx) for e in effects),
        intervals=intervals(extended, steps, cfg),
        limits=detection_limits(
            extended,
            steps,
            prepared.force_kind,
            baseline.sliding_force_N,
            baseline.presliding_m,
            prepared.noise_N,
            cfg,
        ),
        caveats=caveats(
            velocity,
            prepared.standstill_speed_m_s,
            named,
            cfg.caveats,
            near,
            bounded,
            prepared.force_kind,
        ),
    )
