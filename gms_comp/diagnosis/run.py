"""The diagnosis: calibrate, show where the baseline is wrong, fit, select, extend.

1. The baseline is a free NNLS GMS (limits on a log grid of break-away displacements)
   plus, for a drive force, the moving mass, fitted on the training samples. Given a
   GMS table (from the user's bearing), its level, presliding scale and velocity
   dependence are calibrated instead (:mod:`.baseline`), and the table is the baseline
   if its held-out RMS is within ``table_margin`` of the free GMS's (else the free GMS,
   and the JSON says so).
2. Its residual is broken down by motion phase (:mod:`.phases`).
3. Every catalogue effect is fitted as extra design columns (with its own shape grid).
4. Forward selection on held-out samples: an effect is kept only if it lowers the
   held-out RMS by more than ``margin`` (relative), or by a smaller but significant step
   (t statistic over held-out chunks), so noise and baseline mismatch do not
   produce false effects; the kept effects are ranked in the order they were taken.
5. The extended model (GMS + effects) is re-simulated as the compensator would run it,
   and its held-out RMS against the baseline's is the gain.

Held-out samples are every third of ``n_blocks`` contiguous blocks of the trace (so
both parts hold every kind of motion), or a whole second trace when one is given.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import effects as fx
from ..config import in_range, parse_section, positive, read_toml
from ..gms import GmsParams, simulate
from ..traces import ForceKind, Trace
from . import fit
from .baseline import FreeBasis, Samples, TableBasis, calibrate_table, presliding_length
from .motion import BoolArray, FloatArray, Kinematics, kinematics
from .phases import phase_masks, residual_by_phase

DRIVE_CUTOFF_HZ = 100.0
# Joint refits with the GMS force updated (enough for the scaling effects to settle).
JOINT_REFITS = 3
# Relative steps of the local search on shape parameters after the grid.
REFINE_STEPS = (1.3, 1.08)
# Contiguous chunks of held-out samples for the significance of an improvement.
SIGNIFICANCE_CHUNKS = 20
# Effects whose shape is searched again by training RMS in the joint refit.
REFIT_SHAPES = (fx.DwellTime,)


@dataclass(frozen=True)
class DiagnosisConfig:
    """The ``[diagnosis]`` section."""

    # 0: automatic - almost no filtering for a friction force (presliding after a
    # reversal takes a few samples), the benchmark's 100 Hz for a drive force (it needs
    # an acceleration).
    filter_cutoff_Hz: float = field(default=0.0, metadata=in_range(0.0, 1e9))
    n_elements: int = field(default=8, metadata=in_range(1, 40))
    n_blocks: int = field(default=10, metadata=in_range(3, 1000))
    # An effect is kept if it lowers the held-out RMS by more than ``margin`` (relative),
    # or by more than ``small_margin`` with a t statistic over held-out chunks of at
    # least ``significance_t`` (a small but consistent gain, e.g. diluted by a large
    # unexplained part; the t test alone rejects large gains confined to a few chunks).
    margin: float = field(default=0.05, metadata=in_range(0.0, 1.0))
    small_margin: float = field(default=0.01, metadata=in_range(0.0, 1.0))
    significance_t: float = field(default=4.0, metadata=in_range(0.0, 1e3))
    # ... and only if it changes the model force by at least this fraction of the sliding
    # force (smaller terms do not matter for compensation; on clean traces they are the
    # free GMS's mismatch with the true one).
    min_effect_fraction: float = field(default=0.02, metadata=in_range(0.0, 1.0))
    max_effects: int = field(default=6, metadata=in_range(1, 9))
    unknown_ratio: float = field(default=2.0, metadata=positive())
    standstill_speed_fraction: float = field(default=0.01, metadata=in_range(0.0, 1.0))
    # A reversal is a retreat of more than this many position steps: filter ringing after
    # an encoder step is a fraction of a step (raise it above 1 for an encoder that
    # dithers by a count at a standstill).
    reversal_deadband_steps: float = field(default=0.6, metadata=in_range(0.0, 1e3))
    # A calibrated GMS table is the baseline if its held-out RMS is at most this much
    # (relative) above the free NNLS GMS's: its parameters mean something, the free
    # GMS's a little better fit on the training trace may be its flexibility only.
    table_margin: float = field(default=0.1, metadata=in_range(0.0, 10.0))


def load_diagnosis_config(path: str | Path | None) -> DiagnosisConfig:
    if path is None:
        return DiagnosisConfig()
    return parse_section(read_toml(path), path, "diagnosis", DiagnosisConfig)


@dataclass
class _Data:
    """One trace prepared for fitting: kinematics, force, masks and the baseline columns."""

    kin: Kinematics
    force_N: FloatArray
    train: BoolArray
    held: BoolArray
    phi: FloatArray  # the GMS columns of the baseline basis
    base: fit.Columns  # phi (+ acceleration for a drive force)
    ctx: fx.Context | None = None


Basis = FreeBasis | TableBasis


@dataclass
class _Baseline:
    basis: Basis
    datas: list[_Data]
    theta: FloatArray
    info: dict[str, Any]


@dataclass(frozen=True)
class Candidate:
    effect: fx.Effect
    heldout_rms_N: float


@dataclass
class Diagnosis:
    """Result of :func:`diagnose`; :meth:`to_json` gives the spec's keys."""

    effect: str
    ranked: list[Candidate]
    baseline_rms_N: float
    extended_rms_N: float
    baseline: dict[str, Any]
    phases: dict[str, dict[str, float]]
    base_gms: GmsParams  # the baseline's GMS, without the effects' refit
    gms: GmsParams
    extensions: list[fx.Effect]
    noise_rms_N: float
    series: dict[str, FloatArray]  # for the report's plots

    @property
    def gain(self) -> float:
        return 1.0 - self.extended_rms_N / self.baseline_rms_N if self.baseline_rms_N else 0.0

    def to_json(self) -> dict[str, Any]:
        top = self.ranked[0].effect.parameters() if self.ranked else {}
        return {
            "effect": self.effect,
            "effects": [
                {
                    "effect": c.effect.name,
                    "parameters": c.effect.parameters(),
                    "heldout_rms_N": c.heldout_rms_N,
                }
                for c in self.ranked
            ],
            "parameters": top,
            "baseline_rms_N": self.baseline_rms_N,
            "extended_rms_N": self.extended_rms_N,
            "gain": self.gain,
            "noise_rms_N": self.noise_rms_N,
            "baseline": self.baseline,
            "phases": self.phases,
        }


def diagnose(
    trace: Trace,
    force_kind: ForceKind = "friction",
    validation: Trace | None = None,
    config: DiagnosisConfig | None = None,
    table: GmsParams | None = None,
) -> Diagnosis:
    """Diagnose ``trace`` (see the module docstring); ``table``: a GMS table to calibrate
    as the baseline (else the free NNLS GMS)."""
    cfg = config or DiagnosisConfig()
    drive = force_kind == "drive"
    cutoff = cfg.filter_cutoff_Hz or (DRIVE_CUTOFF_HZ if drive else 0.45 / trace.sample_time_s)
    kin = kinematics(trace, cutoff)
    free = FreeBasis(fit.breakaway_grid(kin, cfg.n_elements))
    datas = _prepare(trace, validation, kin, free, drive, cfg.n_blocks, cutoff)
    still_speed = cfg.standstill_speed_fraction * float(np.max(np.abs(kin.velocity_m_s)))
    deadband = cfg.reversal_deadband_steps * fit.position_resolution(trace.position_m)

    chosen_baseline = _baseline(datas, free, table, drive, cfg.table_margin)
    basis, datas, theta = chosen_baseline.basis, chosen_baseline.datas, chosen_baseline.theta
    n_gms = datas[0].phi.shape[1]
    limits = theta[:n_gms]
    base_gms = basis.gms(limits)
    for d in datas:
        force = d.phi @ limits
        d.ctx = fx.Context.along(
            d.kin.time_s,
            d.kin.position_m,
            d.kin.velocity_m_s,
            d.kin.acceleration_m_s2,
            force,
            still_speed,
            deadband,
        )
    base_pred = [d.base.values @ theta for d in datas]
    baseline_rms = _held_rms(datas, base_pred)
    presliding = presliding_length(base_gms)
    sliding = float(np.sum(base_gms.limit_N)) * base_gms.slip_level
    ranked, chosen = _select(datas, cfg, drive, presliding, sliding)

    final, ranked = _joint_refit(datas, chosen, ranked, n_gms)
    gms = basis.gms(final[:n_gms])
    extensions = [c.effect for c in ranked]
    if drive:
        extensions.append(fx.Inertia(float(final[n_gms])))
    extended_pred = [_run_extended(d, gms, extensions) for d in datas]
    extended_rms = _held_rms(datas, extended_pred)
    main = datas[0]
    assert main.ctx is not None
    residual = main.force_N - base_pred[0]
    held_res = np.concatenate(
        [d.force_N[d.held] - p[d.held] for d, p in zip(datas, extended_pred, strict=True)]
    )
    noise = fit.rms(np.diff(held_res)) / np.sqrt(2.0)
    effect = ranked[0].effect.name if ranked else "none"
    if not ranked and baseline_rms > cfg.unknown_ratio * noise:
        effect = "unknown"
    mass = float(theta[n_gms]) if drive else 0.0
    return Diagnosis(
        effect=effect,
        ranked=ranked,
        baseline_rms_N=baseline_rms,
        extended_rms_N=extended_rms,
        baseline={
            "model": "free_nnls_gms" if isinstance(basis, FreeBasis) else "table_gms",
            **chosen_baseline.info,
            "force_kind": force_kind,
            "breakaway_m": basis.breakaway_m.tolist(),
            "limit_N": base_gms.limit_N.tolist(),
            "slip_level": base_gms.slip_level,
            "sliding_force_N": sliding,
            "presliding_m": presliding,
            "mass_kg": mass,
        },
        phases=residual_by_phase(residual, phase_masks(main.ctx, presliding)),
        base_gms=base_gms,
        gms=gms,
        extensions=extensions,
        noise_rms_N=noise,
        series={
            "time_s": main.kin.time_s,
            "position_m": main.kin.position_m,
            "velocity_m_s": main.kin.velocity_m_s,
            "force_N": main.force_N,
            "baseline_N": base_pred[0],
            "extended_N": extended_pred[0],
            **(
                {
                    "validation_force_N": datas[1].force_N,
                    "validation_baseline_N": base_pred[1],
                    "validation_extended_N": extended_pred[1],
                }
                if len(datas) > 1
                else {}
            ),
        },
    )


def _prepare(
    trace: Trace,
    validation: Trace | None,
    kin: Kinematics,
    basis: Basis,
    drive: bool,
    n_blocks: int,
    cutoff_Hz: float,
) -> list[_Data]:
    def data(k: Kinematics, force: FloatArray, held: BoolArray) -> _Data:
        return _Data(k, force, ~held, held, *_base_columns(k, basis, drive))

    n = len(trace)
    if validation is None:
        block = np.arange(n) * n_blocks // n
        return [data(kin, trace.force_N, block % 3 == 1)]
    vkin = kinematics(validation, cutoff_Hz)
    return [
        data(kin, trace.force_N, np.zeros(n, dtype=bool)),
        data(vkin, validation.force_N, np.ones(len(validation), dtype=bool)),
    ]


def _base_columns(kin: Kinematics, basis: Basis, drive: bool) -> tuple[FloatArray, fit.Columns]:
    """The basis's GMS columns and the baseline design (+ acceleration for a drive force)."""
    phi = basis.columns(kin)
    cols = [phi, kin.acceleration_m_s2[:, None]] if drive else [phi]
    return phi, fit.Columns(np.column_stack(cols), np.zeros(sum(c.shape[1] for c in cols)))


def _baseline(
    datas: list[_Data], free: FreeBasis, table: GmsParams | None, drive: bool, margin: float
) -> _Baseline:
    """The free NNLS GMS, or the calibrated ``table`` if its held-out RMS is within
    ``margin`` (relative) of the free GMS's; ``info`` holds both RMS values and the
    table's calibrated factors."""
    theta = _fit_train(datas, [d.base for d in datas])
    free_rms = _held_rms(datas, [d.base.values @ theta for d in datas])
    info: dict[str, Any] = {"source": "free_nnls", "free_nnls_heldout_rms_N": free_rms}
    if table is None:
        return _Baseline(free, datas, theta, info)
    basis = calibrate_table(table, [Samples(d.kin, d.force_N, d.train) for d in datas], drive)
    table_datas = [
        dataclasses.replace(d, phi=phi, base=base)
        for d, (phi, base) in ((d, _base_columns(d.kin, basis, drive)) for d in datas)
    ]
    table_theta = _fit_train(table_datas, [d.base for d in table_datas])
    table_rms = _held_rms(table_datas, [d.base.values @ table_theta for d in table_datas])
    info.update(
        table_heldout_rms_N=table_rms,
        level_factor=float(table_theta[0]),
        presliding_factor=basis.presliding_factor,
        slip_level_factor=basis.slip_level_factor,
        transition_velocity_m_s=basis.params.transition_velocity_m_s,
    )
    if table_rms <= (1.0 + margin) * free_rms:
        return _Baseline(basis, table_datas, table_theta, {**info, "source": "table"})
    return _Baseline(free, datas, theta, info)


def _fit_train(datas: Sequence[_Data], columns: Sequence[fit.Columns]) -> FloatArray:
    a = np.concatenate([c.values[d.train] for d, c in zip(datas, columns, strict=True)])
    y = np.concatenate([d.force_N[d.train] for d in datas])
    return fit.solve(a, y, columns[0].lower)


def _held_rms(datas: Sequence[_Data], predictions: Sequence[FloatArray]) -> float:
    return fit.rms(_held_residual(datas, predictions))


@dataclass(frozen=True)
class _Option:
    """An effect with fixed shape: how it changes the design."""

    effect: type[fx.Effect]
    shape: dict[str, float]

    @property
    def is_filter(self) -> bool:
        return issubclass(self.effect, fx.FilterEffect)

    def filter_effect(self) -> fx.FilterEffect:
        effect = fx.effect_from_dict({"effect": self.effect.name, "parameters": self.shape})
        assert isinstance(effect, fx.FilterEffect)
        return effect

    def extend(self, d: _Data, cols: fit.Columns) -> fit.Columns:
        assert d.ctx is not None
        if self.is_filter:
            filt = self.filter_effect()
            return fit.Columns(filt.filter_columns(cols.values, d.ctx.sample_time_s), cols.lower)
        extra = fit.effect_columns(self.effect, d.ctx, self.shape)
        return fit.Columns(
            np.column_stack([cols.values, extra.values]), np.concatenate([cols.lower, extra.lower])
        )


def _options(
    effect: type[fx.Effect], d: _Data, residual: FloatArray, presliding: float
) -> list[_Option]:
    assert d.ctx is not None
    if effect is fx.SensorLowpass:
        nyquist = 0.5 / d.ctx.sample_time_s
        return [
            _Option(effect, {"cutoff_Hz": float(fc), "order": float(order)})
            for fc in np.geomspace(nyquist / 100, nyquist / 2, 10)
            for order in (1, 2)
        ]
    if effect is fx.DriveLag:
        dt = d.ctx.sample_time_s
        lags = np.geomspace(0.05 * dt, 3 * dt, 12)
        return [_Option(effect, {"lag_s": float(lag)}) for lag in lags]
    moving = d.ctx.moving > 0
    return [
        _Option(effect, s)
        for s in fit.shape_grid(effect, d.kin, d.ctx, residual, moving, presliding)
    ]


def _design(datas: Sequence[_Data], chosen: Sequence[_Option]) -> list[fit.Columns]:
    out = []
    for d in datas:
        cols = d.base
        # a sensor filter acts on everything else, so it is applied last
        for opt in sorted(chosen, key=lambda o: o.is_filter):
            cols = opt.extend(d, cols)
        out.append(cols)
    return out


def _score(
    datas: Sequence[_Data], columns: Sequence[fit.Columns]
) -> tuple[float, FloatArray, FloatArray]:
    """Held-out RMS, coefficients and held-out residual of a design fitted on training."""
    theta = _fit_train(datas, columns)
    held = _held_residual(datas, [c.values @ theta for c in columns])
    return fit.rms(held), theta, held


def _held_residual(datas: Sequence[_Data], predictions: Sequence[FloatArray]) -> FloatArray:
    return np.concatenate(
        [d.force_N[d.held] - p[d.held] for d, p in zip(datas, predictions, strict=True)]
    )


def _kept(
    cfg: DiagnosisConfig, rms: float, held: FloatArray, new_rms: float, new_held: FloatArray
) -> bool:
    """Whether the held-out drop from ``rms`` to ``new_rms`` is worth an effect."""
    if new_rms <= (1.0 - cfg.margin) * rms:
        return True
    small = new_rms <= (1.0 - cfg.small_margin) * rms
    return small and _significance(held, new_held) >= cfg.significance_t


def _significance(current: FloatArray, new: FloatArray) -> float:
    """t statistic of the drop in squared held-out residual, over contiguous chunks
    (residuals are correlated in time, chunks much less so)."""
    gain = np.array([np.mean(c) for c in np.array_split(current**2 - new**2, SIGNIFICANCE_CHUNKS)])
    spread = float(np.std(gain, ddof=1)) / np.sqrt(gain.size)
    return float(np.mean(gain)) / spread if spread > 0 else np.inf


def _select(
    datas: Sequence[_Data],
    cfg: DiagnosisConfig,
    drive: bool,
    presliding: float,
    level_N: float,
) -> tuple[list[Candidate], list[_Option]]:
    """Forward selection: each round takes the effect with the lowest held-out RMS if
    the drop is worth it (:func:`_kept`) and the effect is large enough to matter: it
    changes the model force somewhere (a dwell gain acts only at break-aways) by at
    least ``min_effect_fraction`` of the sliding force. A free GMS is not the truth's GMS, so
    on a clean trace some tiny stray term always lowers the held-out error a little."""
    # a drive force has its mass in the baseline; only a drive command can lead the force
    pool = [e for e in fx.CATALOGUE.values() if e is not (fx.Inertia if drive else fx.DriveLag)]
    chosen: list[_Option] = []
    ranked: list[Candidate] = []
    current, _, current_held = _score(datas, _design(datas, chosen))
    main = datas[0]
    while pool and len(chosen) < cfg.max_effects:
        cols = _design(datas, chosen)
        theta = _fit_train(datas, cols)
        model = cols[0].values @ theta
        residual = main.force_N - model
        best: tuple[float, _Option, FloatArray, FloatArray] | None = None
        for effect in pool:
            for opt in _options(effect, main, residual, presliding):
                score, th, held = _score(datas, _design(datas, [*chosen, opt]))
                if best is None or score < best[0]:
                    best = (score, opt, th, held)
        if best is None:
            break
        best = _refine(datas, chosen, best)
        if not _kept(cfg, current, current_held, best[0], best[3]):
            break
        score, opt, th, current_held = best
        change = _design(datas, [*chosen, opt])[0].values @ th - model
        if np.max(np.abs(change)) < cfg.min_effect_fraction * level_N:
            break
        chosen.append(opt)
        pool.remove(opt.effect)
        current = score
        ranked.append(Candidate(_effect_of(opt, chosen, th, datas), score))
    return ranked, chosen


def _refine(
    datas: Sequence[_Data],
    chosen: Sequence[_Option],
    best: tuple[float, _Option, FloatArray, FloatArray],
) -> tuple[float, _Option, FloatArray, FloatArray]:
    """The best option after a local search on its shape parameters by held-out RMS."""

    def held_rms(opt: _Option) -> float:
        return _score(datas, _design(datas, [*chosen, opt]))[0]

    opt = _local_search(best[1], held_rms, best[0])
    if opt is best[1]:
        return best
    score, th, held = _score(datas, _design(datas, [*chosen, opt]))
    return score, opt, th, held


def _local_search(opt: _Option, cost: Callable[[_Option], float], start_cost: float) -> _Option:
    """Local search on ``opt``'s shape parameters (relative steps shrinking from the
    grids' spacing), so that they are not limited to the grid."""
    best, best_cost = opt, start_cost
    for step in REFINE_STEPS:
        improved = True
        while improved:
            improved = False
            centre = best
            for key in centre.shape:
                if key == "order":
                    continue
                for factor in (1.0 / step, step):
                    trial = _Option(
                        centre.effect, {**centre.shape, key: centre.shape[key] * factor}
                    )
                    trial_cost = cost(trial)
                    if trial_cost < best_cost:
                        best, best_cost, improved = trial, trial_cost, True
    return best


def _joint_refit(
    datas: Sequence[_Data], chosen: Sequence[_Option], ranked: Sequence[Candidate],
    n_elements: int,
) -> tuple[FloatArray, list[Candidate]]:  # fmt: skip
    """All linear parameters fitted jointly with every kept effect present.

    The effects that scale the friction (stribeck, dwell_time, drift) are columns of the
    GMS force; it is updated to the jointly fitted GMS and the fit repeated, so that
    they scale the force the extended model will run with (the shapes of
    ``REFIT_SHAPES`` searched again each time)."""
    theta = _fit_train(datas, _design(datas, chosen))
    for _ in range(JOINT_REFITS if chosen else 0):
        for d in datas:
            assert d.ctx is not None
            d.ctx = dataclasses.replace(d.ctx, gms_force_N=d.phi @ theta[:n_elements])
        chosen = _refine_shapes_on_train(datas, chosen)
        theta = _fit_train(datas, _design(datas, chosen))
    refitted = [
        Candidate(_effect_of(o, chosen, theta, datas), c.heldout_rms_N)
        for o, c in zip(chosen, ranked, strict=True)
    ]
    return theta, refitted


def _train_rms(datas: Sequence[_Data], chosen: Sequence[_Option]) -> float:
    columns = _design(datas, chosen)
    theta = _fit_train(datas, columns)
    return fit.rms(
        np.concatenate(
            [
                d.force_N[d.train] - (c.values @ theta)[d.train]
                for d, c in zip(datas, columns, strict=True)
            ]
        )
    )


def _refine_shapes_on_train(datas: Sequence[_Data], chosen: Sequence[_Option]) -> list[_Option]:
    """The kept effects with the shapes of those in ``REFIT_SHAPES`` searched again, all
    effects present, by training RMS. The selection chose them by held-out RMS with the
    baseline's GMS force: there a dwell's gain and time constant trade off and the
    choice biased both (tau by 15-30 % on simulated traces)."""
    out = list(chosen)
    for i, opt in enumerate(chosen):
        if opt.effect not in REFIT_SHAPES:
            continue

        def train_rms(trial: _Option, i: int = i) -> float:
            return _train_rms(datas, [*out[:i], trial, *out[i + 1 :]])

        out[i] = _local_search(opt, train_rms, _train_rms(datas, out))
    return out


def _effect_of(
    opt: _Option, chosen: Sequence[_Option], theta: FloatArray, datas: Sequence[_Data]
) -> fx.Effect:
    """The effect with the coefficients ``theta`` holds for it in the design of ``chosen``."""
    if opt.is_filter:
        return opt.filter_effect()
    start = datas[0].base.values.shape[1]
    for other in chosen:
        if other.is_filter:
            continue
        assert datas[0].ctx is not None
        width = fit.effect_columns(other.effect, datas[0].ctx, other.shape).values.shape[1]
        if other is opt:
            return opt.effect.from_coefficients(theta[start : start + width], opt.shape)
        start += width
    raise AssertionError("option not in the design")


def _run_extended(d: _Data, gms: GmsParams, extensions: Sequence[fx.Effect]) -> FloatArray:
    """The extended model run as the compensator runs it: GMS kernel, then the effects."""
    assert d.ctx is not None
    force = simulate(gms, d.kin.position_m, d.kin.velocity_m_s)[0]
    return fx.apply_extensions(extensions, dataclasses.replace(d.ctx, gms_force_N=force))
