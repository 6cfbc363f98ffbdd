"""Stage 1: a trace (and its validation trace) made ready for fitting.

Kinematics from the measured position, training and held-out rows, the standstill speed
and the reversal dead band, and a refusal of traces a diagnosis cannot use (constant or
zero force, no reversal, a single speed), saying what the trace lacks and what to
record instead.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass

import numpy as np
from scipy import stats

from gms_comp.arrays import BoolArray, FloatArray, IntArray
from gms_comp.gms import GmsParams
from gms_comp.measured.diagnosis.config import DiagnosisConfig, SplitConfig
from gms_comp.measured.diagnosis.design import runs
from gms_comp.measured.diagnosis.encoder import step_and_resolution
from gms_comp.measured.diagnosis.motion import Kinematics, dequantised, kinematics
from gms_comp.measured.traces import ForceKind, Trace
from gms_comp.runtime import effects as fx
from gms_comp.runtime.effects.path import REST_HOLD_S
from gms_comp.validation import InputError

# The benchmark's low-pass for a drive force's kinematics.
DRIVE_CUTOFF_HZ = 100.0
# A force whose spread is below this fraction of its magnitude is constant.
CONSTANT_FORCE_FRACTION = 1e-9


@dataclass(frozen=True)
class Part:
    """One trace prepared for fitting: kinematics, force, training and held-out rows, and
    the measured position the path is traced on (:attr:`path_position_m`)."""

    kin: Kinematics
    force_N: FloatArray
    train: BoolArray
    held: BoolArray
    # The path's reversals, rests and distances: the commanded position's where the trace
    # holds one (the axis rings under its loop after a force's step, tens of nm, and
    # each ring was a reversal), else the measured position's, as the compensator sees
    # it (the kinematics' zero-phase low-pass rings where a fast move stops short, and a
    # ring of a count's fraction is a false reversal).
    path_position_m: FloatArray

    def picked(self, every: int) -> Part:
        """Every ``every``-th row of this part, its kinematics the full rate's picked (not
        differenced again at the lower rate: a mass came out 13 % high so)."""
        rows = slice(None, None, every)
        return Part(self.kin.slice(0, None, every), self.force_N[rows], self.train[rows],
                    self.held[rows], self.path_position_m[rows])  # fmt: skip

    @functools.cached_property
    def motion_bases(self) -> dict[tuple[object, ...], FloatArray]:
        """The effect bases along this part that read its motion alone, kept by
        :meth:`~gms_comp.measured.diagnosis.baseline.FittedPart.effect_basis` (a ripple's
        columns were computed again for every baseline: 942 times, 346 distinct, 4 s of
        a trace)."""
        return {}


@dataclass(frozen=True)
class Prepared:
    """The output of :func:`prepare`: the parts (the trace, then any validation trace)."""

    parts: tuple[Part, ...]
    drive: bool
    force_kind: ForceKind
    standstill_speed_m_s: float
    reversal_deadband_m: float
    position_resolution_m: float
    rest_band_m: float
    # the force's noise (standard deviation), white or coloured (:func:`noise_at_rest`):
    # read once, from every sample, and what every test of the diagnosis reads
    noise_N: float = 0.0
    encoder_step_m: float = 0.0  # 0: the position is not on an encoder's counts
    dequantised: bool = False  # the kinematics are from the counts read as motion
    fitted_every: int = 1  # the trace's samples fitted: every k-th (DiagnosisConfig.fit_rate_Hz)
    # when fitted on every k-th sample: the same trace prepared at every sample, where an
    # effect at few events and the fitted model's residual are judged, and the model shown
    every_sample: Prepared | None = None

    @property
    def main(self) -> Part:
        """The trace the diagnosis is about (its residuals, phases and plots)."""
        return self.parts[0]

    def context(self, part: Part, gms_force_N: FloatArray) -> fx.Context:
        """The path context of ``part`` with the GMS force ``gms_force_N``: its
        standstill speed, deadband and rest band, traced on its path position, its
        reversals dated from their turning points (a recorded trace knows them; dated
        where the retreat passed the deadband, as a streaming compensator dates them, a
        reversal transient's amplitude came out far off at slow vertices)."""
        index = next(i for i, p in enumerate(self.parts) if p is part)
        return dataclasses.replace(self._paths[index], gms_force_N=np.asarray(gms_force_N, float))

    @functools.cached_property
    def _paths(self) -> list[fx.Context]:
        """Each part's path context (:meth:`context` without a GMS force), traced once."""
        settings = (self.standstill_speed_m_s, self.reversal_deadband_m, self.rest_band_m)
        return [
            fx.Context.of(
                p.kin, np.zeros_like(p.force_N), *settings, p.path_position_m, hindsight=True
            )
            for p in self.parts
        ]


def force_noise(force_N: FloatArray) -> float:
    """The force's white noise (standard deviation), from the median absolute deviation
    of its second differences (sqrt 6 x the noise; a friction force's own second
    difference is small but at few samples)."""
    d2 = np.diff(force_N, 2)
    if d2.size == 0:
        return 0.0
    return float(stats.median_abs_deviation(d2, scale="normal")) / np.sqrt(6.0)


def rest_rms(values: FloatArray, still: BoolArray, rules: SplitConfig) -> float:
    """RMS of ``values`` over the runs of ``still`` of ``rest_run_samples`` or more, each
    less its straight line (a held level, a slow settling); 0 with fewer than
    ``rest_samples`` such samples."""
    left: list[FloatArray] = []
    for rows in runs(still):
        if rows.size >= rules.rest_run_samples:
            k = np.arange(rows.size, dtype=np.float64)
            run = values[rows]
            left.append(run - np.polyval(np.polyfit(k, run, 1), k))
    n = sum(a.size for a in left)
    if n < rules.rest_samples:
        return 0.0
    return float(np.sqrt(sum(float(np.sum(a**2)) for a in left) / (n - 2 * len(left))))


def unchanged(position_m: FloatArray) -> BoolArray:
    """The samples whose position reads as the one before (an encoder's counts at rest)."""
    same = np.zeros(position_m.size, dtype=bool)
    same[1:] = position_m[1:] == position_m[:-1]
    return same


def noise_at_rest(force_N: FloatArray, position_m: FloatArray, rules: SplitConfig) -> float:
    """The force's noise, white or not: :func:`force_noise`, or the force's spread at rest
    (:func:`rest_rms` where the counts do not change) where that is larger (a sensor's
    low-passed noise reads several times smaller in the second differences)."""
    return max(force_noise(force_N), rest_rms(force_N, unchanged(position_m), rules))


def encoder_force_ratio(gms: GmsParams, prepared: Prepared) -> float:
    """How far the encoder's counts show in a GMS driven by them: the force of the
    elements' stiffness over a count's uniform error (K q / sqrt 12) against the
    force's noise; 0 for a position that is not on an encoder's counts."""
    noise = prepared.noise_N
    if prepared.encoder_step_m <= 0.0 or noise <= 0.0:
        return 0.0
    stiffness = float(np.sum(gms.stiffness_N_per_m[gms.limit_N > 0.0]))
    return stiffness * prepared.encoder_step_m / np.sqrt(12.0) / noise


def prepare(
    trace: Trace, force_kind: ForceKind, validation: Trace | None, cfg: DiagnosisConfig,
    dequantise: bool = False, held: BoolArray | None = None,
) -> Prepared:  # fmt: skip
    """The parts of ``trace`` (held out: every third of ``cfg.n_blocks`` blocks,
    :func:`held_third`) or of ``trace`` and ``validation`` (held out whole); with
    ``dequantise``, the kinematics from the encoder's counts read as motion; ``held``: the
    held-out rows another reading chose (the two are then compared on the same rows). A
    trace sampled at twice ``cfg.fit_rate_Hz`` or faster has its parts picked, those of
    every sample kept as :attr:`Prepared.every_sample`.

    Raises
    ------
    InputError
        When a trace lacks what a diagnosis needs.
    """
    drive = force_kind == "drive"
    cutoff = cfg.filter_cutoff_Hz or (DRIVE_CUTOFF_HZ if drive else 0.45 / trace.sample_time_s)
    step, resolution = step_and_resolution(trace.position_m)
    # a drive force's kinematics are the benchmark's (one 100 Hz low-pass for all)
    accel_cutoff = DRIVE_CUTOFF_HZ if drive else acceleration_cutoff(trace, resolution, cfg.split)
    noise = noise_at_rest(trace.force_N, trace.position_m, cfg.split)  # the counts as read
    read = dequantise and step > 0.0
    if read:
        trace = _dequantised(trace, step)
        validation = None if validation is None else _dequantised(validation, step)
    kin = kinematics(trace, cutoff, accel_cutoff)
    deadband = cfg.reversal_deadband_steps * resolution
    still = cfg.standstill_speed_fraction * float(np.max(np.abs(kin.velocity_m_s)))
    check_usable(trace, kin, deadband, still, cfg.split)
    n = len(trace)
    if validation is None:
        held = _held_rows(kin, still, deadband, cfg, resolution, trace) if held is None else held
        path = trace.commanded_or_measured_position_m
        parts: tuple[Part, ...] = (Part(kin, trace.force_N, ~held, held, path),)
    else:
        vkin = kinematics(validation, cutoff, accel_cutoff)
        check_usable(validation, vkin, deadband, still, cfg.split)
        m = len(validation)
        parts = (
            Part(kin, trace.force_N, np.ones(n, dtype=bool), np.zeros(n, dtype=bool),
                 trace.commanded_or_measured_position_m),
            Part(vkin, validation.force_N, np.zeros(m, dtype=bool), np.ones(m, dtype=bool),
                 validation.commanded_or_measured_position_m),
        )  # fmt: skip
    rest_band = cfg.rest_band_steps * resolution
    full = Prepared(
        parts, drive, force_kind, still, deadband, resolution, rest_band, noise, step, read
    )
    rates = [t.sample_time_s for t in (trace, validation) if t is not None]
    every = [fitted_every(dt, cfg.fit_rate_Hz, cfg.split.max_fitted_every) for dt in rates]
    if max(every) == 1:
        return full
    picked = tuple(p.picked(k) for p, k in zip(parts, every, strict=True))
    return dataclasses.replace(full, parts=picked, fitted_every=every[0], every_sample=full)


def fitted_every(sample_time_s: float, rate_Hz: float, most: int) -> int:
    """Which samples of a trace sampled every ``sample_time_s`` are fitted: every k-th,
    k = floor(its sample rate / ``rate_Hz``) but at most ``most``; 1 for ``rate_Hz`` 0 or
    a slower trace."""
    every = int(1.0 / (sample_time_s * rate_Hz) + 1e-6) if rate_Hz > 0.0 else 1
    return max(1, min(every, most))


def _held_rows(
    kin: Kinematics, still: float, deadband: float, cfg: DiagnosisConfig, resolution: float,
    trace: Trace,
) -> BoolArray:  # fmt: skip
    n = len(trace)
    block = np.arange(n) * cfg.n_blocks // n
    third = block % 3
    rules = cfg.split
    held = third == held_third(
        third, kin, still, deadband, cfg.rest_band_steps * resolution, trace.position_m, rules
    )  # fmt: skip
    for size in (kin.velocity_m_s, kin.acceleration_m_s2):
        held &= ~top_blocks(block, held, np.abs(size), rules)
    return held | top_rows_held(
        block, held, np.abs(kin.velocity_m_s), np.abs(kin.acceleration_m_s2), rules
    )  # fmt: skip


def _dequantised(trace: Trace, step_m: float) -> Trace:
    return dataclasses.replace(trace, position_m=dequantised(trace.position_m, step_m))


def held_third(
    third: IntArray, kin: Kinematics, still_m_s: float, deadband_m: float,
    rest_band_m: float, position_m: FloatArray, rules: SplitConfig,
) -> int:  # fmt: skip
    """Which third of the blocks (``third``: each sample's) to hold out: 1, unless it
    holds fewer than ``held_starts_share`` of a third of the starts after a standstill
    (the path's rests, as the effects see them: a dwell gain acts only there); then the
    one nearest a third of them (1, 0, 2 on ties)."""
    ctx = fx.Context.of(
        kin, np.zeros(third.size), still_m_s, deadband_m, rest_band_m, position_m
    )  # fmt: skip
    starts = ctx.starts(REST_HOLD_S)
    counts = np.bincount(third[starts], minlength=3)
    share = starts.size / 3.0
    if counts[1] >= rules.held_starts_share * share:
        return 1
    return min((1, 0, 2), key=lambda k: abs(float(counts[k]) - share))


def top_blocks(block: IntArray, held: BoolArray, size: FloatArray, rules: SplitConfig) -> BoolArray:
    """The rows of the ``held`` blocks (``block``: each sample's) that reach
    ``train_top_share`` of the top ``size`` (a speed, an acceleration's magnitude), if
    the training rows do not (else none): they are trained on instead (a velocity law or
    a mass is otherwise extrapolated to where it is judged)."""
    reach = rules.train_top_share * float(np.max(size))
    if np.any(size[~held] >= reach):
        return np.zeros(block.size, dtype=bool)
    return np.isin(block, np.unique(block[held & (size >= reach)]))


def top_rows_held(
    block: IntArray, held: BoolArray, speed: FloatArray, accel: FloatArray, rules: SplitConfig
) -> BoolArray:
    """The training rows to hold out (``block``: each sample's) where the ``held`` rows do
    not reach ``held_top_share`` of the top ``speed`` (else none): in the block of the
    median training row that does, split at the median of that block's such rows, the
    later rows to the block's end, or else the earlier ones from its start; a part that
    holds some of those rows and leaves the training rows ``train_top_share`` of the top
    speed and of the top ``accel`` (none if neither does)."""
    none = np.zeros(block.size, dtype=bool)
    top = float(np.max(speed))
    if top <= 0.0 or np.any(speed[held] >= rules.held_top_share * top):
        return none
    fast = ~held & (speed >= rules.held_top_share * top)
    tops = [a >= rules.train_top_share * np.max(a) for a in (speed, accel)]
    rows = np.flatnonzero(fast)
    same = np.flatnonzero(block == block[rows[rows.size // 2]])
    inside = rows[(rows >= same[0]) & (rows <= same[-1])]
    middle = int(inside[inside.size // 2])
    for part in (slice(middle, same[-1] + 1), slice(same[0], middle)):
        out = none.copy()
        out[part] = True
        out &= ~held
        if np.any(out & fast) and all(np.any(~held & ~out & t) for t in tops):
            return out
    return none


def acceleration_cutoff(trace: Trace, resolution_m: float, rules: SplitConfig) -> float:
    """The highest low-pass cut-off (Hz) at which the acceleration's quantisation noise is
    at most ``acceleration_noise_share`` of the acceleration's RMS (the signal read at
    ``DRIVE_CUTOFF_HZ``); the Nyquist frequency if the encoder is fine enough.

    A position step q read every dt gives a second difference of RMS q / sqrt(2) / dt^2,
    its spectrum rising as f^4: the noise below a cut-off f_c falls as (f_c / f_N)^2.5.
    Too noisy, a mass comes out low; filtered too low, high."""
    dt = trace.sample_time_s
    nyquist = 0.5 / dt
    noise = resolution_m / np.sqrt(2.0) / dt**2
    signal = float(np.sqrt(np.mean(kinematics(trace, DRIVE_CUTOFF_HZ).acceleration_m_s2 ** 2)))
    if noise <= 0.0 or signal <= 0.0:
        return nyquist
    ratio = rules.acceleration_noise_share * signal / noise
    return float(nyquist * min(1.0, ratio**0.4))


def check_usable(
    trace: Trace, kin: Kinematics, deadband_m: float, still_m_s: float, rules: SplitConfig
) -> None:
    """Refuse a trace without a varying force, reversals, or several speeds."""
    force = trace.force_N
    size = float(np.max(np.abs(force)))
    if size == 0.0:
        raise InputError(
            trace.source, "force_N",
            "the force is zero throughout (a disconnected sensor?): record the friction or "
            "drive force while the axis moves back and forth",
        )  # fmt: skip
    if float(np.ptp(force)) <= CONSTANT_FORCE_FRACTION * size:
        raise InputError(
            trace.source, "force_N",
            f"the force is constant ({force[0]:.6g} N): a diagnosis needs the force to follow "
            "the motion; check the sensor and record back-and-forth strokes",
        )  # fmt: skip
    x = kin.position_m
    extreme_turns = _reversals(x, max(deadband_m, 1e-12))
    if extreme_turns < rules.min_reversals:
        raise InputError(
            trace.source, "position_m",
            f"the axis reverses {extreme_turns} time(s): a diagnosis needs presliding after "
            "reversals; record back-and-forth strokes (e.g. gms-comp profile)",
        )  # fmt: skip
    speed = np.abs(kin.velocity_m_s)
    moving = speed[speed > max(still_m_s, 1e-12)]
    lo, hi = np.percentile(moving, [10, 90]) if moving.size else (0.0, 0.0)
    if hi <= rules.min_speed_spread * lo:
        raise InputError(
            trace.source, "velocity",
            f"the axis moves at one speed only ({1e3 * float(np.median(moving)):.3g} mm/s): "
            "record strokes at several speeds (e.g. 5, 20 and 50 mm/s) to separate "
            "velocity-dependent effects",
        )  # fmt: skip


def _reversals(x: FloatArray, deadband_m: float) -> int:
    """How often ``x`` retreats by more than ``deadband_m`` from its furthest point."""
    count, direction, extreme = 0, 0.0, float(x[0])
    # the trace decimated to at most 20 000 points keeps every stroke of interest
    for xi in x[:: max(1, x.size // 20000)]:
        step = float(xi) - extreme
        if direction == 0.0:
            if abs(step) > deadband_m:
                direction, extreme = float(np.sign(step)), float(xi)
        elif step * direction >= 0.0:
            extreme = float(xi)
        elif -step * direction > deadband_m:
            direction, extreme, count = -direction, float(xi), count + 1
    return count
