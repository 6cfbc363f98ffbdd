"""Property tests of trace input (issue 74): clocks, units, encodings, headers, sizes.

Traces come from tests/tracefiles.py, which knows nothing of gms_comp: a sine stroke with
its speed and acceleration in closed form, written as a user's logger would. Classes:

- representation: the same motion in any units with the right ``--map``, under any
  header names (quoted or as written), with a BOM or CRLF, reads as the same trace;
- unit slips: a column in ms/us, mm/um/nm or kN without a map is refused in one line
  with the ``--map`` that fixes it, and that map reads the trace right (drawn where the
  slip leaves the range of ball-guided axes by a margin: see docs/traces.md for what
  physics cannot tell, such as cm on a slow short stroke);
- clocks: jitter, and stamps scattered around one clock, are read as recorded; a change of
  rate and missing samples are resampled onto the coarsest held rate and said so; a gap or
  a repeated stamp is refused naming its row; ``--segment`` reads one piece between gaps;
- damaged and huge files: truncated or mutated bytes, sparse files of any size, are
  refused with a TraceError (or read), never another exception.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from tracefiles import Motion, csv_text, jittered, rate_change, repeated, with_gap

from gms_comp.errors import TraceError
from gms_comp.measured import trace_csv
from gms_comp.measured.trace_clock import Segment
from gms_comp.measured.traces import Trace, load_trace, parse_mapping
from gms_comp.validation import MAX_TRACE_BYTES

SETTINGS = settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)


@st.composite
def motions(draw: Any) -> Motion:
    """A stroke any ball-guided axis can make, at 0.1-20 kHz, 200-4000 samples, a period
    or more."""
    rate = draw(st.floats(math.log(100.0), math.log(20e3)).map(math.exp))
    # at least 20 samples a period: a friction trace resolves its reversals (a motion
    # sampled under ~8 times a period reads as position noise: docs/traces.md)
    frequency = draw(st.floats(max(0.2, 1.1 * rate / 4000), min(20.0, rate / 20.0)))
    samples = max(200, math.ceil(1.1 * rate / frequency))
    w = 2 * math.pi * frequency
    top = min(0.2, 2.0 / w, 200.0 / w**2)  # amplitude: <= 2 m/s, <= 200 m/s^2
    assume(top >= 1e-3)
    amplitude = draw(st.floats(math.log(5e-4), math.log(top)).map(math.exp))
    return Motion(
        rate_Hz=rate,
        samples=samples,
        amplitude_m=amplitude,
        frequency_Hz=frequency,
        coulomb_N=draw(st.floats(1.0, 200.0)),
        viscous_Ns_per_m=draw(st.floats(0.0, 50.0)),
        encoder_m=draw(st.sampled_from([1e-9, 1e-8, 1e-7, 1e-6])),
        noise_N=0.01,
        seed=draw(st.integers(0, 2**16)),
    )


def _write(folder: Path, data: bytes, name: str = "t.csv") -> Path:
    path = folder / name
    path.write_bytes(data)
    return path


def _canonical(motion: Motion, folder: Path) -> Trace:
    t, x, f = motion.arrays()
    return load_trace(
        _write(folder, csv_text({"time_s": t, "position_m": x, "force_N": f}), "c.csv")
    )


def _same(a: Trace, b: Trace) -> None:
    assert len(a) == len(b)
    for name in ("time_s", "position_m", "force_N"):
        x, y = getattr(a, name), getattr(b, name)
        np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-12 * float(np.max(np.abs(y))))
    assert a.sample_time_s == pytest.approx(b.sample_time_s, rel=1e-12)


def _one_line(err: pytest.ExceptionInfo[TraceError], path: Path) -> str:
    text = str(err.value)
    assert "\n" not in text and text.startswith(str(path))
    return text


# --- representation ----------------------------------------------------------------------

UNITS = {  # canonical column -> (unit, factor from SI to the file's unit)
    "time_s": [("s", 1.0), ("ms", 1e3), ("us", 1e6)],
    "position_m": [("m", 1.0), ("mm", 1e3), ("um", 1e6), ("cm", 1e2)],
    "force_N": [("N", 1.0), ("kN", 1e-3), ("mN", 1e3)],
}
NAME_CHARS = "abcxyzTF_ 0123456789[]()/+-.:"
NUMBER = re.compile(r"^(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")  # an unquoted name reads as one
names = st.text(NAME_CHARS, min_size=1, max_size=10).filter(lambda s: s == s.strip())


@SETTINGS
@given(
    motion=motions(),
    units=st.fixed_dictionaries({k: st.sampled_from(v) for k, v in UNITS.items()}),
    header=st.lists(names, min_size=3, max_size=3, unique=True),
    quote=st.booleans(),
    bom=st.booleans(),
    crlf=st.booleans(),
)
def test_a_trace_reads_the_same_in_any_units_names_and_encoding(
    tmp_path: Path, motion: Motion, units: dict[str, tuple[str, float]], header: list[str],
    quote: bool, bom: bool, crlf: bool,
) -> None:  # fmt: skip
    assume(quote or not any(NUMBER.match(n) for n in header))
    canonical = _canonical(motion, tmp_path)
    t, x, f = motion.arrays()
    si = {"time_s": t, "position_m": x, "force_N": f}
    columns = {name: si[col] * units[col][1] for name, col in zip(header, si, strict=True)}
    path = _write(tmp_path, csv_text(columns, bom=bom, crlf=crlf))
    written = [f'"{n}"' if quote else n for n in header]
    mapping = parse_mapping(
        [f"{col}={w}*{1.0 / units[col][1]!r}" for w, col in zip(written, si, strict=True)], "--map"
    )
    trace = load_trace(path, mapping)
    _same(trace, canonical)
    assert trace.clock is not None and not trace.clock.resampled


# --- unit slips ----------------------------------------------------------------------------

# (column, unit, factor from SI to the unit, whether physics must catch it for a motion)
SLIPS: list[tuple[str, str, float, Any]] = [
    ("time_s", "ms", 1e3, lambda m: True),  # every rate >= 100 Hz reads below 100 Hz
    ("time_s", "us", 1e6, lambda m: True),
    ("position_m", "um", 1e6, lambda m: True),  # a 1 mm stroke reads as 1000 m
    ("position_m", "nm", 1e9, lambda m: True),
    (  # mm: caught where the stroke, speed or acceleration read in m leaves the range
        "position_m", "mm", 1e3,
        lambda m: 2e3 * m.amplitude_m > 7.5 or 1e3 * m.peak_speed_m_s > 15.0
        or 1e3 * m.peak_acceleration_m_s2 > 1500.0,
    ),
    (  # kN: caught where the force never reaches 0.025 kN
        "force_N", "kN", 1e-3,
        lambda m: m.coulomb_N + m.viscous_Ns_per_m * m.peak_speed_m_s < 15.0,
    ),
]  # fmt: skip


@SETTINGS
@given(motion=motions(), slip=st.sampled_from(SLIPS))
def test_a_unit_slip_is_refused_with_the_map_that_fixes_it(
    tmp_path: Path, motion: Motion, slip: tuple[str, str, float, Any]
) -> None:
    column, unit, factor, caught = slip
    assume(caught(motion))
    canonical = _canonical(motion, tmp_path)
    t, x, f = motion.arrays()
    si = {"time_s": t, "position_m": x, "force_N": f}
    path = _write(tmp_path, csv_text({**si, column: si[column] * factor}))
    with pytest.raises(TraceError) as err:
        load_trace(path)
    text = _one_line(err, path)
    fix = f"{column}={column}*{1.0 / factor:g}"
    assert f"column {column}" in text and f"{unit} (--map {fix})" in text, text
    _same(load_trace(path, parse_mapping([fix], "--map")), canonical)


@SETTINGS
@given(
    motion=motions(),
    factor=st.sampled_from([1e-2, 1e2, 1e-3, 1e3, 1e6]),
    column=st.sampled_from(list(UNITS)),
)
def test_any_scaling_is_read_or_refused_in_one_line(
    tmp_path: Path, motion: Motion, factor: float, column: str
) -> None:
    """Slips physics cannot always tell (cm, a fast trace's mm, mN) are read or refused,
    never a crash."""
    t, x, f = motion.arrays()
    si = {"time_s": t, "position_m": x, "force_N": f}
    path = _write(tmp_path, csv_text({**si, column: si[column] * factor}))
    try:
        load_trace(path)
    except TraceError as err:
        assert "\n" not in str(err) and str(err).startswith(str(path))


# --- clocks ----------------------------------------------------------------------------------


def _file(folder: Path, t: np.ndarray, x: np.ndarray, f: np.ndarray) -> Path:
    return _write(folder, csv_text({"time_s": t, "position_m": x, "force_N": f}))


@SETTINGS
@given(motion=motions(), fraction=st.floats(0.0, 0.45), seed=st.integers(0, 99))
def test_jitter_and_scattered_stamps_are_read_as_recorded(
    tmp_path: Path, motion: Motion, fraction: float, seed: int
) -> None:
    """Stamps within a quarter step of a uniform clock: every sample as recorded (each
    position with its force), on that clock; said when the steps vary over 10 %."""
    t, x, f = motion.arrays()
    stamps = jittered(t, fraction, seed)
    trace = load_trace(_file(tmp_path, stamps, x, f))
    assert trace.clock is not None and not trace.clock.resampled
    np.testing.assert_allclose(trace.position_m, x, rtol=1e-13)
    np.testing.assert_allclose(trace.force_N, f, rtol=1e-13)
    assert trace.sample_time_s == pytest.approx(1.0 / motion.rate_Hz, rel=0.5 / motion.samples)
    steps = np.diff(stamps)
    varied = np.max(np.abs(steps / np.median(steps) - 1.0)) > 0.1
    assert ("stamp_scatter_steps" in trace.clock.to_json()) == varied


@SETTINGS
@given(motion=motions(), every=st.integers(2, 4), share=st.floats(0.2, 0.8))
def test_a_change_of_rate_is_resampled_onto_the_coarser_rate_and_said_so(
    tmp_path: Path, motion: Motion, every: int, share: float
) -> None:
    t, x, f = motion.arrays()
    assume(motion.samples // every >= 150 and motion.rate_Hz / every >= 100.0)
    at = int(share * motion.samples) // every * every
    kept = rate_change(motion.samples, at, every)
    trace = load_trace(_file(tmp_path, t[kept], x[kept], f[kept]))
    clock = trace.clock
    assert clock is not None and clock.resampled
    assert clock.sample_rate_Hz == pytest.approx(motion.rate_Hz / every, rel=1e-6)
    low, high = clock.to_json()["resampled_from_Hz"]
    assert (low, high) == (pytest.approx(motion.rate_Hz / every), pytest.approx(motion.rate_Hz))
    # the coarse grid falls on recorded samples: the trace holds them, nothing invented
    coarse = np.arange(0, motion.samples, every)[: len(trace)]
    np.testing.assert_allclose(trace.position_m, x[coarse], atol=1e-9 * np.ptp(x))
    np.testing.assert_allclose(trace.force_N, f[coarse], atol=1e-9 * np.ptp(f))


@SETTINGS
@given(motion=motions(), where=st.lists(st.floats(0.05, 0.95), min_size=1, max_size=3),
       missing=st.integers(1, 3))  # fmt: skip
def test_missing_samples_are_interpolated_on_the_recorded_clock(
    tmp_path: Path, motion: Motion, where: list[float], missing: int
) -> None:
    t, x, f = motion.arrays()
    dropped = {int(w * motion.samples) + k for w in where for k in range(missing)}
    kept = np.array([i for i in range(motion.samples) if i not in dropped])
    assume(kept[-1] == motion.samples - 1 and np.max(np.diff(kept)) <= 4)  # <= 3 in a row
    trace = load_trace(_file(tmp_path, t[kept], x[kept], f[kept]))
    assert trace.clock is not None and trace.clock.resampled
    assert trace.clock.sample_rate_Hz == pytest.approx(motion.rate_Hz, rel=1e-9)
    assert len(trace) == motion.samples
    np.testing.assert_allclose(trace.position_m[kept], x[kept], atol=1e-9 * np.ptp(x))
    expected = np.interp(t, t[kept], x[kept])  # straight lines across the missing ones
    np.testing.assert_allclose(trace.position_m, expected, atol=1e-9 * np.ptp(x))


@SETTINGS
@given(motion=motions(), share=st.floats(0.1, 0.9), steps=st.floats(math.log(5.0), math.log(1e8)))
def test_a_gap_is_refused_with_its_row_and_a_segment_reads_one_piece(
    tmp_path: Path, motion: Motion, share: float, steps: float
) -> None:
    t, x, f = motion.arrays()
    at = max(1, int(share * motion.samples))
    stamps = with_gap(t, at, math.exp(steps) / motion.rate_Hz)
    path = _file(tmp_path, stamps, x, f)
    with pytest.raises(TraceError) as err:
        load_trace(path)
    text = _one_line(err, path)
    assert f"row {at + 2}, column time_s: a gap of" in text and "--segment" in text
    pieces = [(0, at), (at, motion.samples)]
    choices: list[tuple[Segment, tuple[int, int]]] = [
        (1, pieces[0]),
        (2, pieces[1]),
        ("longest", max(pieces, key=lambda p: p[1] - p[0])),
    ]
    for choice, (a, b) in choices:
        if b - a < 100:
            with pytest.raises(TraceError, match="samples, the analysis needs"):
                load_trace(path, segment=choice)
            continue
        piece = load_trace(path, segment=choice)
        np.testing.assert_allclose(piece.position_m, x[a:b], rtol=1e-13)
        np.testing.assert_allclose(piece.time_s, stamps[a:b], rtol=1e-13)
        assert piece.clock is not None and piece.clock.segments == 2


@SETTINGS
@given(motion=motions(), share=st.floats(0.01, 0.99))
def test_a_repeated_stamp_is_refused_with_its_row(
    tmp_path: Path, motion: Motion, share: float
) -> None:
    t, x, f = motion.arrays()
    at = max(1, int(share * motion.samples))
    path = _file(tmp_path, repeated(t, at), x, f)
    with pytest.raises(TraceError) as err:
        load_trace(path)
    assert f"row {at + 2}, column time_s: time stamp" in _one_line(err, path)


# --- damaged and huge files ------------------------------------------------------------------


@settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    cut=st.floats(0.0, 1.0),
    flips=st.lists(st.tuples(st.floats(0.0, 1.0), st.binary(min_size=1, max_size=4)), max_size=3),
    bom=st.booleans(),
)
def test_a_truncated_or_mutated_file_is_read_or_refused_in_one_line(
    tmp_path: Path, cut: float, flips: list[tuple[float, bytes]], bom: bool
) -> None:
    motion = Motion(1000.0, 300, 5e-3, 2.0, 10.0)
    t, x, f = motion.arrays()
    data = bytearray(csv_text({"time_s": t, "position_m": x, "force_N": f}, bom=bom))
    for where, new in flips:
        i = int(where * (len(data) - 1))
        data[i : i + len(new)] = new
    path = _write(tmp_path, bytes(data[: int(cut * len(data))]))
    try:
        load_trace(path)
    except TraceError as err:
        assert "\n" not in str(err) and str(err).startswith(str(path))


@pytest.mark.parametrize(
    ("body", "size", "says"),
    [
        (b"", MAX_TRACE_BYTES + 1, "more than the"),  # sparse: all zeros
        (b"", 10 << 30, "more than the"),
        (b"time_s,position_m,force_N\n", 100 << 20, "not UTF-8 text"),  # a header, then zeros
        (
            b"time_s,position_m,force_N\n" + b"0.0000000000000000000000000001,0,0\n" * 2000,
            100 << 20,
            "NUL byte",
        ),  # rows of the size the zeros would hold, then zeros
        (b"time_s,position_m,force_N\n" + b"0,0,0\n" * 20000, 200 << 20, "about"),
        (b"\xff\xfet\x00i\x00m\x00e\x00", 1000, "UTF-16"),
        (b"time_s;position_m;force_N\n0;0;0\n", 0, "separated by ';'"),
        (b"time_s,position_m,force_N,time_s\n0,0,0,0\n", 0, "duplicate column names"),
    ],
)
def test_sizes_and_encodings_are_refused_before_parsing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, body: bytes, size: int, says: str
) -> None:
    path = tmp_path / "big.csv"
    with path.open("wb") as fh:
        fh.write(body)
        fh.truncate(max(size, len(body)))  # sparse: no disk spent on the zeros
    monkeypatch.setattr(np, "loadtxt", _never)  # refused before any parsing
    with pytest.raises(TraceError, match=says):
        load_trace(path)
    assert os.path.getsize(path) >= size


def _never(*args: object, **kwargs: object) -> None:
    raise AssertionError("the file must be refused before it is parsed")


def test_a_bom_and_quoted_names_are_read(tmp_path: Path) -> None:
    motion = Motion(1000.0, 300, 5e-3, 2.0, 10.0)
    t, x, f = motion.arrays()
    canonical = _canonical(motion, tmp_path)
    columns = {"time, s": t, 'pos "x" [um]': x * 1e6, "F (N)": f}
    path = _write(tmp_path, csv_text(columns, bom=True, crlf=True))
    mapping = parse_mapping(
        ['time_s="time, s"', 'position_m="pos ""x"" [um]"*1e-6', "force_N=F (N)"], "--map"
    )
    _same(load_trace(path, mapping), canonical)
    assert trace_csv.read_csv(path)[0].keys() == columns.keys()
