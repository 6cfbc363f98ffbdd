"""Stage 6: is what the extended model leaves noise, or structure no effect explains?

The held-out residual is averaged over bins of each quantity a friction effect could
depend on (motion phase, velocity, position and direction, time) and searched for a tone;
the RMS of the bin means, less the noise's share, is what depends on the quantity. Where
the largest stands well above the noise and is a share of the sliding force worth
compensating (or the residual as a whole stands far above the noise), the answer is
``unknown`` and the findings say where the residual lives. A spot (a fraction of a mm
where the level changes) is searched on every sample, and must show with the other sign
where the same bin is travelled the other way (friction acts both ways). The bin means are
compared with what noise gives them: the diagnosis's noise (``Prepared.noise_N``) or the
white part of the residual tested (its sample-to-sample changes, which no bin can hold),
whichever is larger.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gms_comp.arrays import BoolArray, FloatArray
from gms_comp.measured.diagnosis.baseline import FittedPart
from gms_comp.measured.diagnosis.config import StructureConfig
from gms_comp.measured.diagnosis.design import rms
from gms_comp.measured.diagnosis.phases import ACCELERATION_FRACTION, phase_label, phase_masks

BINS = 16
# per direction: a local feature (a bump, a damaged spot) is a fraction of a mm wide
POSITION_BINS = 24
TONE_HALF_WIDTH = 2  # bins either side of a tone's peak
# The most findings a description names.
DESCRIBED = 3


@dataclass(frozen=True)
class Finding:
    """How much of the residual depends on one quantity, and where it is largest."""

    by: str
    rms_N: float
    where: str


@dataclass(frozen=True)
class Structure:
    """The output of :func:`residual_structure`."""

    noise_rms_N: float
    findings: tuple[Finding, ...]  # largest first
    structured: bool
    # what a finding holds to be structure on its own (the thresholds' larger)
    floor_N: float = np.inf

    def description(self) -> str:
        """The structured findings in words (empty when the residual is noise-like): the
        largest, then at most ``DESCRIBED - 1`` more that are half its size or structure
        on their own (a spot on a time modulation, and its tone and position)."""
        if not self.structured:
            return ""
        first, *rest = self.findings
        big = [f for f in rest if f.rms_N >= min(0.5 * first.rms_N, self.floor_N)]
        return "; ".join(f.where for f in [first, *big][:DESCRIBED])

    def to_json(self) -> dict[str, Any]:
        """The findings for the diagnosis JSON."""
        return {
            "structured": self.structured,
            "description": self.description(),
            "noise_rms_N": self.noise_rms_N,
            "by": {f.by: {"rms_N": f.rms_N, "where": f.where} for f in self.findings},
        }


def _grouped(residual: FloatArray, groups: FloatArray, noise: float) -> tuple[float, int, float]:
    """RMS of the group means above the noise's share; the group with the largest
    contribution and its mean."""
    keys, inverse, counts = np.unique(groups, return_inverse=True, return_counts=True)
    means = np.bincount(inverse, weights=residual) / counts
    n = residual.size
    power = float(np.sum(counts * means**2) / n - keys.size * noise**2 / n)
    top = int(np.argmax(counts * means**2))
    return float(np.sqrt(max(power, 0.0))), top, float(means[top])


def _quantile_bins(x: FloatArray, n: int) -> FloatArray:
    edges = np.quantile(x, np.linspace(0, 1, n + 1)[1:-1])
    return np.searchsorted(edges, x).astype(np.float64)


def _tone(residual: FloatArray, sample_time_s: float, prominence: float) -> tuple[float, float]:
    """RMS and frequency of the strongest narrow tone of ``residual`` (0 if none)."""
    if residual.size < 64:
        return 0.0, 0.0
    spectrum = np.abs(np.fft.rfft(residual - np.mean(residual))) ** 2
    spectrum[0] = 0.0
    k = int(np.argmax(spectrum))
    if spectrum[k] < prominence * float(np.median(spectrum[1:])):
        return 0.0, 0.0
    band = spectrum[max(1, k - TONE_HALF_WIDTH) : k + TONE_HALF_WIDTH + 1]
    power = 2.0 * float(np.sum(band)) / residual.size**2
    return float(np.sqrt(power)), k / (residual.size * sample_time_s)


def _longest_run(mask: BoolArray) -> slice:
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    starts, stops = edges[::2], edges[1::2]
    i = int(np.argmax(stops - starts)) if starts.size else 0
    return slice(int(starts[i]), int(stops[i])) if starts.size else slice(0, 0)


def residual_structure(
    parts: Sequence[FittedPart], predictions: Sequence[FloatArray], presliding_m: float,
    level_N: float, noise: float, rules: StructureConfig,
) -> Structure:  # fmt: skip
    """Where the held-out residual of ``predictions`` depends on phase, velocity,
    position and direction, time, or holds a tone; ``structured`` when the largest part
    is at least ``unknown_ratio`` x the noise and ``unknown_fraction`` x ``level_N``, or
    the residual itself ``unexplained_ratio`` x the noise and above it
    ``unknown_fraction`` x ``level_N``."""
    ratio, fraction = rules.unknown_ratio, rules.unknown_fraction
    residuals = [fp.part.force_N - y for fp, y in zip(parts, predictions, strict=True)]
    res, vel, pos, dirn, t, phase = [], [], [], [], [], []
    for j, (fp, residual) in enumerate(zip(parts, residuals, strict=True)):
        held = fp.part.held
        res.append(residual[held])
        vel.append(fp.ctx.velocity_m_s[held])
        pos.append(fp.ctx.position_m[held])
        dirn.append(fp.ctx.direction[held])
        t.append(fp.ctx.time_s[held] + 1e6 * j)
        labels = np.full(held.size, -1.0)
        masks = phase_masks(fp.ctx, presliding_m)
        for i, mask in enumerate(masks.values()):
            labels[mask & (labels < 0)] = i + 100 * j
        phase.append(labels[held])
    r = np.concatenate(res)
    noise = max(noise, rms(np.diff(r)) / np.sqrt(2.0))  # the residual's white part
    v, x, d = np.concatenate(vel), np.concatenate(pos), np.concatenate(dirn)
    findings = [_phase_finding(r, np.concatenate(phase), parts, presliding_m, noise)]
    moving = _moving(v)
    if np.count_nonzero(moving) > 4 * BINS:
        vb = _quantile_bins(v[moving], BINS)
        size, top, mean = _grouped(r[moving], vb, noise)
        v_top = float(np.median(v[moving][vb == np.unique(vb)[top]]))
        where = f"(largest, {mean:+.3g} N, near {1e3 * v_top:+.3g} mm/s)"
        findings.append(Finding("velocity", size, f"the level depends on the velocity {where}"))
        xb = _quantile_bins(x[moving], POSITION_BINS) + POSITION_BINS * (d[moving] > 0)
        size, top, mean = _grouped(r[moving], xb, noise)
        key = np.unique(xb)[top]
        x_top = float(np.median(x[moving][xb == key]))
        way = "forward" if key >= POSITION_BINS else "backward"
        split = _grouped(r[moving], (d[moving] > 0).astype(float), noise)[0]
        words = "on the direction of motion and " if split >= 0.5 * size else ""
        findings.append(Finding("position", size, f"the level depends {words}on the position "
                                f"(largest, {mean:+.3g} N, near x = {1e3 * x_top:.4g} mm moving "
                                f"{way})"))  # fmt: skip
    tb = np.minimum((np.arange(r.size) * BINS) // r.size, BINS - 1).astype(float)
    size, top, mean = _grouped(r, tb, noise)
    t_all = np.concatenate(t)
    t_top = float(np.median(t_all[tb == top]) % 1e6)
    findings.append(Finding("time", size, f"the level drifts over time (largest, {mean:+.3g} N, "
                            f"around t = {t_top:.3g} s)"))  # fmt: skip
    main = parts[-1]  # the validation trace when there is one, else the trace
    run = _longest_run(main.part.held)
    first = int(np.count_nonzero(main.part.held[: run.start]))
    tone, freq = _tone(
        res[-1][first : first + run.stop - run.start], main.ctx.sample_time_s,
        rules.tone_prominence,
    )  # fmt: skip
    findings.append(Finding("frequency", tone, f"a tone at {freq:.4g} Hz"))
    findings.sort(key=lambda f: f.rms_N, reverse=True)
    floor = max(ratio * noise, fraction * level_N)
    structured = bool(findings[0].rms_N >= floor)
    unexplained = None if structured else _unexplained(r, noise, fraction * level_N, level_N, rules)
    if unexplained is not None:
        findings.insert(0, unexplained)
        structured = True
    spot = _spot_everywhere(parts, residuals, noise, rules)
    if spot is not None and spot.rms_N >= max(
        rules.spot_ratio * noise, rules.spot_fraction * level_N
    ):
        findings.insert(0, spot)
        structured = True
    return Structure(noise, tuple(findings), structured, floor)


def _unexplained(
    residual: FloatArray, noise: float, floor_N: float, level_N: float, rules: StructureConfig
) -> Finding | None:
    """The residual as a whole, if its RMS is ``unexplained_ratio`` x ``noise`` or more
    and what stands above the noise at least ``floor_N``; else None."""
    left = rms(residual)
    above = float(np.sqrt(max(left**2 - noise**2, 0.0)))
    if left < rules.unexplained_ratio * noise or above < floor_N:
        return None
    return Finding("residual", above, (
        f"what the model leaves stands {left / noise:.2g} x the noise ({100 * above / level_N:.2g} "
        f"% of the sliding force), more than any one quantity holds"
    ))  # fmt: skip


def _moving(velocity_m_s: FloatArray) -> BoolArray:
    """The samples faster than 1 % of the top speed."""
    return np.abs(velocity_m_s) > 0.01 * float(np.max(np.abs(velocity_m_s)))


def _spot_everywhere(
    parts: Sequence[FittedPart], residuals: Sequence[FloatArray], noise: float,
    rules: StructureConfig,
) -> Finding | None:  # fmt: skip
    """:func:`_spot` on every moving sample of every part (fitted and held out), given
    each part's whole residual."""
    r = np.concatenate(residuals)
    v = np.concatenate([fp.ctx.velocity_m_s for fp in parts])
    x = np.concatenate([fp.ctx.position_m for fp in parts])
    d = np.concatenate([fp.ctx.direction for fp in parts])
    a = np.concatenate([fp.ctx.acceleration_m_s2 for fp in parts])
    moving = _moving(v)
    if np.count_nonzero(moving) <= 4 * BINS:
        return None
    steady = np.abs(a[moving]) <= ACCELERATION_FRACTION * float(np.max(np.abs(a)))
    return _spot(r[moving], x[moving], d[moving], noise, rules, steady)


def _binned(r: FloatArray, key: FloatArray, noise: float) -> tuple[FloatArray, ...]:
    """The keys of ``key``, and the count, mean and z (mean over its standard error) of
    ``r`` in each."""
    keys, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    means = np.bincount(inverse, weights=r) / counts
    return keys, counts.astype(np.float64), means, np.abs(means) * np.sqrt(counts) / noise


def _spot(
    r: FloatArray, x: FloatArray, d: FloatArray, noise: float, rules: StructureConfig,
    steady: BoolArray | None = None,
) -> Finding | None:  # fmt: skip
    """The largest significant mean of the residual over ``spot_width_m`` of travel one
    way (its size that mean), or None: with the opposite sign where the same bin is
    travelled the other way; where it is not, on the ``steady`` samples, with the next bin
    the same way beside it."""
    if noise <= 0.0:
        return None
    width = rules.spot_width_m
    key = np.floor(x / width) * 2 + (d > 0)
    keys, counts, means, z = _binned(r, key, noise)
    # the same bin the other way: key + 1 from backward (even), key - 1 from forward
    other = keys + np.where(keys % 2 == 0, 1.0, -1.0)
    at = np.clip(np.searchsorted(keys, other), 0, keys.size - 1)
    travelled = (keys[at] == other) & (counts[at] >= rules.spot_partner_samples)
    partner = travelled & (np.sign(means[at]) == -np.sign(means)) & (z[at] >= rules.spot_partner_z)
    ok = (counts >= rules.spot_min_samples) & (z >= rules.spot_z) & partner
    other_way = [f"{means[at[i]]:+.3g} N the other way" for i in range(keys.size)]
    found = [(float(abs(means[i])), _words(keys[i], means[i], width, other_way[i]))
             for i in np.flatnonzero(ok)]  # fmt: skip
    if steady is not None and np.any(steady):
        one_way = keys[~travelled]
        keys, counts, means, z = _binned(r[steady], key[steady], noise)
        seen = np.isin(keys, one_way)
        beside = np.zeros(keys.size, dtype=bool)
        for step in (-2.0, 2.0):  # the next bin the same way, either side
            at = np.clip(np.searchsorted(keys, keys + step), 0, keys.size - 1)
            beside |= (
                (keys[at] == keys + step)
                & (np.sign(means[at]) == np.sign(means))
                & (z[at] >= rules.spot_partner_z)
            )
        ok = seen & beside & (counts >= rules.spot_one_way_samples) & (z >= rules.spot_z)
        one = "not crossed the other way"
        found += [(float(abs(means[i])), _words(keys[i], means[i], width, one))
                  for i in np.flatnonzero(ok)]  # fmt: skip
    if not found:
        return None
    size, where = max(found)
    return Finding("spot", size, where)


def _words(key: float, mean: float, width: float, other: str) -> str:
    centre = (np.floor(key / 2) + 0.5) * width
    way = "forward" if key % 2 else "backward"
    return (f"the level changes locally ({mean:+.3g} N over {1e3 * width:.3g} mm near "
            f"x = {1e3 * centre:.4g} mm moving {way}, {other})")  # fmt: skip


def _phase_finding(
    r: FloatArray, labels: FloatArray, parts: Sequence[FittedPart], presliding_m: float,
    noise: float,
) -> Finding:  # fmt: skip
    size, top, mean = _grouped(r, labels, noise)
    key = int(np.unique(labels)[top])
    name = "no phase"
    if key >= 0:
        names = list(phase_masks(parts[key // 100].ctx, presliding_m))
        name = phase_label(names[key % 100])
    return Finding("phase", size, f"the residual is largest in {name} (mean {mean:+.3g} N)")
