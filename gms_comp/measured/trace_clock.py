"""The clock of a trace: its time stamps read as one uniform sampling, or refused.

The diagnosis differentiates and filters at one sample step, so a trace reaches it on a
uniform clock, and how that clock was read is part of the result (:class:`Clock`, the
diagnosis JSON's ``input``). The policy, in this order (docs/traces.md):

1. Time increases: a repeated stamp or one that goes back is refused with its row.
2. Used as recorded, at the mean step: when every step is within ``MAX_CLOCK_JITTER`` of
   the median (timer jitter, rounded stamps), or when the stamps scatter by at most
   ``MAX_STAMP_SCATTER_STEPS`` around one uniform clock (stamps taken on receipt).
   Otherwise the grid step is the coarsest step the recorder held over at least
   ``MIN_RATE_SHARE`` of the trace (the median step of blocks of ``RATE_BLOCK_STEPS``),
   so that no rate the recorder did not have is invented.
3. Its rate lies within [``MIN_SAMPLE_RATE_HZ``, ``MAX_SAMPLE_RATE_HZ``]; outside, the
   time column's unit is wrong (stamps in ms read as s are 1000 times slower) and the
   refusal names the ``--map`` that scales it.
4. A step longer than ``MAX_GAP_STEPS`` grid steps is a gap: the axis moved unobserved.
   The trace is refused, naming the first gap and its segments, unless a segment is
   chosen (``--segment N`` or ``longest``); no analysis spans a gap.
5. A trace (or segment) whose steps are not all within the jitter of the grid step
   (missing samples, a change of rate, large jitter) is resampled onto the grid by
   linear interpolation, and its :class:`Clock` says so (``resampled_from_Hz``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np

from gms_comp.arguments import int_in_range
from gms_comp.arrays import FloatArray
from gms_comp.errors import TraceError
from gms_comp.measured.trace_map import scaled
from gms_comp.validation import MAX_TRACE_SAMPLES

#: Largest departure of a time step from the trace's median step, as a fraction of it,
#: still read as one uniform clock (timer jitter; stamps printed with few digits, 333 and
#: 334 us at 3 kHz, differ by 0.3 %); beyond it the samples are placed at their stamps.
MAX_CLOCK_JITTER = 0.1
#: Largest distance of the stamps from a uniform clock fitted through them, in its steps,
#: read as that clock with each sample as recorded: stamps taken on receipt scatter
#: around the sampling clock, and reading the samples on it keeps each position and
#: force measured together (interpolating at scattered stamps would mix neighbours;
#: a sample missing moves every later stamp by a step, far beyond it).
MAX_STAMP_SCATTER_STEPS = 0.25
#: Longest time step, in grid steps, interpolated over (up to three missing samples in a
#: row, within the clock's jitter); a longer one is a gap in which the axis moved
#: unobserved.
MAX_GAP_STEPS = 4.0
#: Share of a trace's duration over which a sample rate must be held to set the grid of
#: a trace sampled at several rates (a brief slow-down of the recorder does not decimate
#: the whole trace).
MIN_RATE_SHARE = 0.1
#: Slowest sample rate, Hz: presliding after a reversal and a break-away last a few ms,
#: which a slower record does not resolve; and every rate from here to the fastest read
#: with its stamps in ms falls below it (a 1 kHz trace in ms reads as 1 Hz), so ms and
#: us stamps are always refused.
MIN_SAMPLE_RATE_HZ = 100.0
#: Fastest sample rate, Hz: drives and test stands log at up to tens of kHz; a faster
#: clock is a time column in another unit, or a record to decimate first.
MAX_SAMPLE_RATE_HZ = 100e3

# Steps per block whose median is one reading of the recorder's rate (a missing sample
# or two in a block do not move it).
RATE_BLOCK_STEPS = 32

Segment = int | Literal["longest"]


def segment_choice(value: str) -> Segment:
    """An argparse ``type`` for ``--segment``: a piece number from 1, or ``longest``."""
    if value.strip().lower() == "longest":
        return "longest"
    return int_in_range(1, MAX_TRACE_SAMPLES)(value)


@dataclass(frozen=True)
class Clock:
    """How a trace's time stamps were read."""

    sample_rate_Hz: float  # the uniform rate the analysis uses
    recorded_Hz: tuple[float, float]  # slowest and fastest rate of the used steps
    resampled: bool = False  # linear interpolation onto the uniform grid
    segment: int = 1  # which piece between gaps (1-based)
    segments: int = 1  # pieces between gaps in the file
    rows: tuple[int, int] = (0, 0)  # first and last sample index of the used piece
    # the stamps' largest distance from the uniform clock they were read on, in steps,
    # when their steps varied more than MAX_CLOCK_JITTER (else None)
    scatter: float | None = None

    def to_json(self) -> dict[str, Any]:
        """The JSON's ``input``: the rate, and how it was read when not as recorded."""
        doc: dict[str, Any] = {"sample_rate_Hz": self.sample_rate_Hz}
        if self.resampled:
            doc["resampled_from_Hz"] = list(self.recorded_Hz)
        if self.segments > 1:
            doc["segment"] = {
                "index": self.segment,
                "of": self.segments,
                "samples": list(self.rows),
            }
        if self.scatter is not None:
            doc["stamp_scatter_steps"] = self.scatter
        return doc

    def describe(self) -> str:
        """One line for the summary, or "" for a trace used as recorded."""
        parts = []
        if self.segments > 1:
            parts.append(
                f"segment {self.segment} of {self.segments} (samples {self.rows[0] + 1}-"
                f"{self.rows[1] + 1}, between gaps in time)"
            )
        if self.scatter is not None:
            parts.append(
                f"time stamps scattered by up to {self.scatter:.2g} of a step around a uniform "
                f"{self.sample_rate_Hz:.6g} Hz clock: the samples read on that clock"
            )
        if self.resampled:
            low, high = self.recorded_Hz
            recorded = f"{low:.6g} Hz" if low == high else f"{low:.6g}-{high:.6g} Hz"
            parts.append(
                f"recorded at {recorded}, resampled onto a uniform {self.sample_rate_Hz:.6g} Hz "
                "clock by linear interpolation"
            )
        return "; ".join(parts)


@dataclass(frozen=True)
class ClockReading:
    """Which samples to use and where: ``grid_s`` is None when they are used as recorded."""

    start: int
    stop: int
    grid_s: FloatArray | None
    clock: Clock


def read_clock(
    time_s: FloatArray,
    source: str,
    where: Callable[[int], str],
    time_expr: str = "time_s",
    segment: Segment | None = None,
) -> ClockReading:
    """The uniform clock of ``time_s`` by the module's policy.

    Parameters
    ----------
    time_s
        The time stamps, s (finite; at least two).
    source, where
        The file, and the row of a sample index, for refusals.
    time_expr
        The mapping expression of the time column, for a suggested ``--map``.
    segment
        Which piece between gaps to use (1-based, or the longest); None refuses gaps.

    Raises
    ------
    TraceError
        Time not increasing, a rate out of range, a gap without a segment chosen.
    """
    steps = np.diff(time_s)
    _check_increasing(time_s, steps, source, where)
    n = time_s.size
    recorded = (1.0 / float(np.max(steps)), 1.0 / float(np.min(steps)))
    scatter = None if _uniform(steps) else _scatter(time_s)
    if scatter is None or scatter <= MAX_STAMP_SCATTER_STEPS:
        rate = (n - 1) / float(time_s[-1] - time_s[0])
        _check_rate(1.0 / rate, source, time_expr)
        _chosen([(0, n)], segment, source)
        return ClockReading(0, n, None, Clock(rate, recorded, rows=(0, n - 1), scatter=scatter))
    grid_step = _grid_step(steps)
    _check_rate(grid_step, source, time_expr)
    pieces = _pieces(steps, grid_step)
    if len(pieces) > 1 and segment is None:
        raise _gap_error(time_s, steps, grid_step, pieces, source, where)
    index = _chosen(pieces, segment, source)
    start, stop = pieces[index]
    if len(pieces) > 1:  # the piece's own clock (its rate may differ from the whole's)
        if stop - start < 2:
            raise TraceError(source, "column time_s", f"segment {index + 1} holds one sample")
        inner = read_clock(time_s[start:stop], source, lambda i: where(i + start), time_expr)
        clock = replace(
            inner.clock, segment=index + 1, segments=len(pieces), rows=(start, stop - 1)
        )
        return ClockReading(start, stop, inner.grid_s, clock)
    duration = float(time_s[-1] - time_s[0])
    steps_held = duration / grid_step
    if abs(steps_held - round(steps_held)) <= MAX_CLOCK_JITTER:  # the last sample on the grid
        grid_step = duration / round(steps_held)
    count = int(np.floor(duration / grid_step + MAX_CLOCK_JITTER)) + 1
    if count > MAX_TRACE_SAMPLES:
        raise TraceError(
            source, "column time_s",
            f"resampled onto its {1.0 / grid_step:.6g} Hz clock it would hold {count} samples, "
            f"more than the {MAX_TRACE_SAMPLES} a trace may have; cut the record into parts",
        )  # fmt: skip
    grid = time_s[0] + grid_step * np.arange(count)
    return ClockReading(0, n, grid, Clock(1.0 / grid_step, recorded, True, rows=(0, n - 1)))


def _uniform(steps: FloatArray) -> bool:
    """Every step within ``MAX_CLOCK_JITTER`` of the median step."""
    return bool(np.max(np.abs(steps / np.median(steps) - 1.0)) <= MAX_CLOCK_JITTER)


def _scatter(time_s: FloatArray) -> float:
    """The stamps' largest distance from the uniform clock fitted through them (least
    squares over the sample index), in steps of that clock."""
    index = np.arange(time_s.size, dtype=float)
    index -= index.mean()
    centred = time_s - time_s.mean()
    step = float(index @ centred / (index @ index))
    return float(np.max(np.abs(centred - step * index))) / step


def _grid_step(steps: FloatArray) -> float:
    """The coarsest step held over ``MIN_RATE_SHARE`` of the trace (gaps do not count:
    blocks' medians ignore them), at least the median step."""
    median = float(np.median(steps))
    blocks = steps.size // RATE_BLOCK_STEPS
    if blocks == 0:
        return median
    readings = np.sort(np.median(steps[: blocks * RATE_BLOCK_STEPS].reshape(blocks, -1), axis=1))
    # rates within the jitter of a cluster's first reading are one rate
    first = 0
    best = median
    total = float(np.sum(readings))
    for i in range(1, blocks + 1):
        if i == blocks or readings[i] > readings[first] * (1.0 + MAX_CLOCK_JITTER):
            cluster = readings[first:i]
            if float(np.sum(cluster)) >= MIN_RATE_SHARE * total:
                best = max(best, float(np.median(cluster)))
            first = i
    return best


def _check_increasing(
    time_s: FloatArray, steps: FloatArray, source: str, where: Callable[[int], str]
) -> None:
    bad = np.flatnonzero(steps <= 0.0)
    if bad.size == 0:
        return
    i = int(bad[0])
    a, b = float(time_s[i]), float(time_s[i + 1])
    if b == a:
        repeats = int(np.count_nonzero(steps == 0.0))
        more = f" ({repeats} stamps repeat their row before)" if repeats > 1 else ""
        raise TraceError(
            source, f"{where(i + 1)}, column time_s",
            f"time stamp {b:.9g} s repeats the row before{more}: remove duplicate rows, or "
            "write the time with more digits than one sample step needs",
        )  # fmt: skip
    raise TraceError(
        source, f"{where(i + 1)}, column time_s", f"time does not increase ({a:.9g} -> {b:.9g} s)"
    )


# A rate within this fraction of a bound is at the bound (the mean step of a jittered
# clock, the rounding of printed stamps).
_ROUNDING = 0.01
# Units a time column is found in, most common first, with their factor to seconds.
_TIME_UNITS = (("ms", 1e-3), ("us", 1e-6))


def _check_rate(step: float, source: str, time_expr: str) -> None:
    rate = 1.0 / step
    if MIN_SAMPLE_RATE_HZ * (1 - _ROUNDING) <= rate <= MAX_SAMPLE_RATE_HZ * (1 + _ROUNDING):
        return
    seen = f"samples {step:.4g} s apart ({rate:.4g} Hz)"
    if rate < MIN_SAMPLE_RATE_HZ:
        units = [
            f"{name} (--map time_s={scaled(time_expr, factor)})"
            for name, factor in _TIME_UNITS
            if MIN_SAMPLE_RATE_HZ <= rate / factor <= MAX_SAMPLE_RATE_HZ
        ]
        record = f"record at {MIN_SAMPLE_RATE_HZ:g} Hz or faster"
        fix = f"the time looks like {' or '.join(units)}; if not, {record}" if units else record
        raise TraceError(
            source, "column time_s",
            f"{seen}, slower than the {MIN_SAMPLE_RATE_HZ:g} Hz a friction trace needs: {fix}",
        )  # fmt: skip
    raise TraceError(
        source, "column time_s",
        f"{seen}, faster than the {MAX_SAMPLE_RATE_HZ:g} Hz of any axis log: if the time is "
        f"not in seconds, scale it (--map time_s={scaled(time_expr, 60)} for minutes); "
        "otherwise decimate the record first",
    )  # fmt: skip


def _pieces(steps: FloatArray, grid_step: float) -> list[tuple[int, int]]:
    """Sample ranges [start, stop) between gaps."""
    gaps = np.flatnonzero(steps > MAX_GAP_STEPS * (1.0 + MAX_CLOCK_JITTER) * grid_step)
    starts = [0, *(int(g) + 1 for g in gaps)]
    stops = [*(int(g) + 1 for g in gaps), steps.size + 1]
    return list(zip(starts, stops, strict=True))


def _chosen(pieces: list[tuple[int, int]], segment: Segment | None, source: str) -> int:
    if segment is None or segment == "longest":
        return max(range(len(pieces)), key=lambda k: pieces[k][1] - pieces[k][0])
    if not 1 <= segment <= len(pieces):
        raise TraceError(
            source, "--segment",
            f"{segment}: the trace has {len(pieces)} segment{'s' if len(pieces) > 1 else ''} "
            "between gaps in time",
        )  # fmt: skip
    return segment - 1


def _gap_error(
    time_s: FloatArray, steps: FloatArray, grid_step: float, pieces: list[tuple[int, int]],
    source: str, where: Callable[[int], str],
) -> TraceError:  # fmt: skip
    gap = pieces[1][0] - 1
    size = float(steps[gap])
    shown = ", ".join(f"{where(a)}-{where(b - 1).removeprefix('row ')}" for a, b in pieces[:4])
    shown += ", ..." if len(pieces) > 4 else ""
    return TraceError(
        source, f"{where(gap + 1)}, column time_s",
        f"a gap of {size:.4g} s in time ({time_s[gap]:.9g} -> {time_s[gap + 1]:.9g} s, "
        f"{size / grid_step:.3g} sample steps; the axis moved unobserved): the trace is "
        f"{len(pieces)} segments ({shown}); diagnose one with --segment N (1-{len(pieces)}) "
        "or --segment longest, or split the file",
    )  # fmt: skip
