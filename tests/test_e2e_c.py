"""The C reference handler and the Python receiver agree on the same test vectors.

The C pack/unpack code is generated from the DBC at test time (the DBC stays the
single source), compiled with the hand-written handler, and driven via ctypes.
"""

from __future__ import annotations

import ctypes
import random
import shutil
import subprocess
import sys

import pytest
from cantools.autosar import compute_profile5_crc
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_bridge.profiles.e2e.codec import E2eCodec, default_dbc_path, profile5_crc
from firmware_bridge.profiles.e2e.receiver import E2eReceiver
from firmware_bridge.resources import packaged_path
from firmware_bridge.supervisor import Supervisor, Verdict

C_DIR = packaged_path("c")
VERDICTS = list(Verdict)
TIMEOUT, RAMP, MAX_AGE, LIMIT = 3, 4, 1, 20000
CYCLE_US = 1000

pytestmark = pytest.mark.skipif(
    shutil.which("gcc") is None, reason="gcc is not installed: the C handler cannot be built"
)


class CConfig(ctypes.Structure):
    _fields_ = [  # the layout of struct ff_config
        ("data_id", ctypes.c_uint16),
        ("limit_raw", ctypes.c_int16),
        ("timeout_cycles", ctypes.c_uint32),
        ("ramp_cycles", ctypes.c_uint32),
        ("max_age_cycles", ctypes.c_uint32),
        ("cycle_us", ctypes.c_uint32),
        ("transport_cycles", ctypes.c_uint32),
        ("slot_margin_us", ctypes.c_uint32),
    ]


@pytest.fixture(scope="module")
def lib(tmp_path_factory: pytest.TempPathFactory) -> ctypes.CDLL:
    out = tmp_path_factory.mktemp("ffc")
    subprocess.run(
        [
            sys.executable,
            "-m",
            "cantools",
            "generate_c_source",
            str(default_dbc_path()),
            "-o",
            str(out),
        ],
        check=True,
        capture_output=True,
    )
    so = out / "libff.so"
    subprocess.run(
        [
            "gcc",
            "-std=c99",
            "-O2",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-shared",
            "-fPIC",
            "-I",
            str(out),
            "-I",
            str(C_DIR),
            str(out / "gms_ff.c"),
            str(C_DIR / "ff_handler.c"),
            "-o",
            str(so),
        ],
        check=True,
        capture_output=True,
        text=True,
    )
    lib = ctypes.CDLL(str(so))
    lib.ff_handler_size.restype = ctypes.c_size_t
    lib.ff_on_frame.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_size_t]
    lib.ff_tick.restype = ctypes.c_int16
    lib.ff_tick_at.restype = ctypes.c_int16
    lib.ff_tick_at.argtypes = [ctypes.c_void_p, ctypes.c_uint32]
    lib.ff_on_frame_at.argtypes = [
        ctypes.c_void_p,
        ctypes.c_char_p,
        ctypes.c_size_t,
        ctypes.c_uint32,
    ]
    lib.ff_crc16.restype = ctypes.c_uint16
    lib.ff_crc16.argtypes = [ctypes.c_char_p, ctypes.c_size_t, ctypes.c_uint16]
    return lib


class CHandler:
    def __init__(self, lib: ctypes.CDLL, data_id: int) -> None:
        self.lib = lib
        self.mem = ctypes.create_string_buffer(lib.ff_handler_size())
        cfg = CConfig(data_id, LIMIT, TIMEOUT, RAMP, MAX_AGE, CYCLE_US, 1, CYCLE_US // 4)
        lib.ff_init(self.mem, ctypes.byref(cfg))

    def frame(self, data: bytes) -> Verdict:
        return VERDICTS[self.lib.ff_on_frame(self.mem, data, len(data))]

    def tick(self) -> int:
        return int(self.lib.ff_tick(self.mem))

    def frame_at(self, data: bytes, rx_us: int) -> Verdict:
        return VERDICTS[self.lib.ff_on_frame_at(self.mem, data, len(data), rx_us % 2**32)]

    def tick_at(self, now_us: int) -> int:
        return int(self.lib.ff_tick_at(self.mem, now_us % 2**32))


def py_handler(codec: E2eCodec) -> E2eReceiver:
    return E2eReceiver(codec, Supervisor(LIMIT, TIMEOUT, RAMP), MAX_AGE)


Event = tuple[str, bytes]


def run_both(lib: ctypes.CDLL, events: list[Event]) -> tuple[list[object], list[object]]:
    codec = E2eCodec()
    c, py = CHandler(lib, codec.command_data_id), py_handler(codec)
    c_out: list[object] = []
    py_out: list[object] = []
    for kind, data in events:
        if kind == "frame":
            c_out.append(c.frame(data))
            py_out.append(py.on_frame(data))
        else:
            c_out.append(c.tick())
            py_out.append(py.tick())
    return c_out, py_out


def vectors(seed: int, n: int = 400) -> list[Event]:
    """A stream with every kind of fault: drops, delays, duplicates, replays, bit flips, gaps."""
    codec = E2eCodec()
    rng = random.Random(seed)
    sent: list[bytes] = []
    events: list[Event] = []
    held: dict[int, list[bytes]] = {}
    for cycle in range(n):
        raw = rng.randint(-32767, 32767)
        frame = codec.encode_command(cycle, raw)
        sent.append(frame)
        events.extend(("frame", old) for old in held.pop(cycle, []))
        r = rng.random()
        if r < 0.05 or 200 <= cycle < 215:  # dropped, and one outage
            pass
        elif r < 0.10:
            flipped = bytearray(frame)
            flipped[rng.randrange(8)] ^= 1 << rng.randrange(8)
            events.append(("frame", bytes(flipped)))
        elif r < 0.15 and len(sent) > 3:
            events.append(("frame", sent[-rng.randint(2, 4)]))  # replayed old frame
            events.append(("frame", frame))
        elif r < 0.25:  # delayed by 1..3 cycles
            held.setdefault(cycle + rng.randint(1, 3), []).append(frame)
        else:
            events.append(("frame", frame))
            if r > 0.95:
                events.append(("frame", frame))  # duplicate
        events.append(("tick", b""))
    return events


@pytest.mark.parametrize("seed", range(5))
def test_c_and_python_agree_on_fault_vectors(lib: ctypes.CDLL, seed: int) -> None:
    c_out, py_out = run_both(lib, vectors(seed))
    assert c_out == py_out
    assert {v for v in py_out if isinstance(v, Verdict)} >= {
        Verdict.ACCEPTED,
        Verdict.CORRUPT,
        Verdict.DUPLICATE,
        Verdict.OUT_OF_ORDER,
        Verdict.STALE,
    }


TimedEvent = tuple[str, bytes, int]


def timed_vectors(seed: int) -> list[TimedEvent]:
    """:func:`vectors` on a real-time drive's timer, in microseconds from near the
    32-bit wrap: drive cycle ``k`` begins at ``T0 + k ms`` (the tick after it, at
    ``T0 + (k + 1) ms``, applies it); a frame of cycle ``k`` leaves at the seed's phase
    in the cycle plus up to 0.3 ms of jitter and is received then, or, held up (the
    generator's delays and replays), anywhere in the cycle it is handed over."""
    rng = random.Random(1000 + seed)
    t0 = 2**32 - 37 * CYCLE_US - rng.randrange(CYCLE_US)  # the timer wraps in cycle ~37
    # even seeds: the compensator's cycles begin within 0.1 cycle after the drive's ticks
    phase = rng.randrange(CYCLE_US // 10 if seed % 2 == 0 else CYCLE_US)
    out: list[TimedEvent] = []
    cycle = 0
    for kind, data in vectors(seed):
        if kind == "tick":
            cycle += 1
            out.append(("tick", b"", t0 + cycle * CYCLE_US))
            continue
        start = t0 + cycle * CYCLE_US
        own = E2eCodec().check_command(data)
        on_time = own is not None and own[0] == cycle % 256
        leave = start + phase + rng.randrange(300)
        rx = leave if on_time else start + rng.randrange(CYCLE_US)
        out.append(("frame", data, max(start, min(rx, start + CYCLE_US - 1))))
    return out


def run_both_timed(
    lib: ctypes.CDLL, events: list[TimedEvent]
) -> tuple[list[object], list[object], list[int], list[int]]:
    """The C handler with its timer and the real-time Python receiver with seconds."""
    codec = E2eCodec()
    c = CHandler(lib, codec.command_data_id)
    py = E2eReceiver(codec, Supervisor(LIMIT, TIMEOUT, RAMP), MAX_AGE, CYCLE_US * 1e-6)
    py.set_real_time(True)
    c_out: list[object] = []
    py_out: list[object] = []
    for kind, data, t_us in events:
        if kind == "frame":
            c_out.append(c.frame_at(data, t_us))
            py_out.append(py.on_frame(data, t_us * 1e-6))
        else:
            c_out.append(c.tick_at(t_us))
            py_out.append(py.tick(t_us * 1e-6))
    counts = [int(c.lib.ff_count(c.mem, i)) for i in range(len(VERDICTS))]
    return c_out, py_out, counts, [py.counts.counts[v] for v in VERDICTS]


@pytest.mark.parametrize("seed", range(8))
def test_c_and_python_agree_on_timed_fault_vectors(lib: ctypes.CDLL, seed: int) -> None:
    """By time too (slot, margin, the timer's wrap): same verdicts, outputs and counts.
    The rule by time refuses more than the counter alone, and strictly more when the
    compensator's cycles begin within the margin after the drive's ticks (even seeds)."""
    c_out, py_out, c_counts, py_counts = run_both_timed(lib, timed_vectors(seed))
    assert c_out == py_out
    assert c_counts == py_counts
    untimed = run_both(lib, [(kind, data) for kind, data, _ in timed_vectors(seed)])[1]
    by_counter = sum(v is Verdict.STALE for v in untimed)
    by_time = py_counts[VERDICTS.index(Verdict.STALE)]
    assert by_time > by_counter if seed % 2 == 0 else by_time >= by_counter


def test_c_refuses_a_held_frame_by_its_slot_like_python(lib: ctypes.CDLL) -> None:
    """The hand-worked case of tests/test_can_reception_age.py on the C timer: frames on
    time 50 us after the ticks; counter 2 left at 1.99 ms, held until 3.95 ms: fresh by
    its counter (age 1), 1.01 cycles old at the 4 ms tick, refused by its slot less the
    margin (2.05 - 0.25 ms: 1.2 cycles)."""
    codec = E2eCodec()
    c = CHandler(lib, codec.command_data_id)
    assert c.frame_at(codec.encode_command(0, 5), 50) is Verdict.RESYNC
    c.tick_at(1000)
    assert c.frame_at(codec.encode_command(1, 6), 1050) is Verdict.ACCEPTED
    assert c.tick_at(2000) == 6
    c.tick_at(3000)
    assert c.frame_at(codec.encode_command(2, 7), 3950) is Verdict.ACCEPTED
    assert c.tick_at(4000) == 6  # held, not 7
    assert c.lib.ff_count(c.mem, VERDICTS.index(Verdict.STALE)) == 1


@pytest.mark.parametrize("late_by", range(MAX_AGE + 3))
def test_c_and_python_date_a_late_frame_alike_at_the_boundary(
    lib: ctypes.CDLL, late_by: int
) -> None:
    """Frame 0 sets the reference; frame 1 arrives ``late_by`` cycles after its own cycle:
    applied up to MAX_AGE cycles late (boundary included), stale beyond."""
    codec = E2eCodec()
    events: list[Event] = [("frame", codec.encode_command(0, 100)), ("tick", b"")]
    events += [("tick", b"")] * late_by
    events.append(("frame", codec.encode_command(1, 200)))
    c_out, py_out = run_both(lib, events)
    expected = Verdict.ACCEPTED if late_by <= MAX_AGE else Verdict.STALE
    assert c_out == py_out and py_out[-1] is expected


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.one_of(
            st.just(("tick", b"")), st.binary(min_size=0, max_size=9).map(lambda b: ("frame", b))
        ),
        max_size=60,
    )
)
def test_c_and_python_agree_on_arbitrary_bytes(lib: ctypes.CDLL, events: list[Event]) -> None:
    c_out, py_out = run_both(lib, events)
    assert c_out == py_out


def test_out_of_range_current_is_corrupt_in_both(lib: ctypes.CDLL) -> None:
    codec = E2eCodec()
    data = bytearray(8)
    data[2] = 1
    data[3:5] = (-32768).to_bytes(2, "little", signed=True)  # outside the DBC's [-32767, 32767]
    crc = compute_profile5_crc(bytes(data), codec.command_data_id)
    assert crc is not None
    data[0:2] = crc.to_bytes(2, "little")
    c_out, py_out = run_both(lib, [("frame", bytes(data))])
    assert c_out == py_out == [Verdict.CORRUPT]


@settings(max_examples=100, deadline=None)
@given(st.binary(min_size=8, max_size=8), st.integers(0, 0xFFFF))
def test_c_and_python_crc_match_cantools_profile5(
    lib: ctypes.CDLL, payload: bytes, data_id: int
) -> None:
    expected = compute_profile5_crc(payload, data_id)
    assert lib.ff_crc16(payload[2:], 6, data_id) == expected
    assert profile5_crc(payload, data_id) == expected
