"""The C reference handler and the Python receiver agree on the same event sequences.

The C pack/unpack code is generated from the DBC at test time (the DBC stays the
single source), compiled with the hand-written handler, and driven via ctypes. Besides
agreeing with each other, both are held to the rule of firmware_bridge.freshness by an
audit written here: a command is applied only at a tick ``n`` with ``0 <= n - stamp <=
MAX_AGE``, only in the session the drive granted, and a link that delays every frame
by more than the window never gets one applied, however long the delay lasts.
"""

from __future__ import annotations

import ctypes
import random
import shutil
import subprocess
import sys
from dataclasses import dataclass, field

import pytest
from cantools.autosar import compute_profile5_crc
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_bridge.freshness import Mode
from firmware_bridge.profiles.e2e.codec import E2eCodec, default_dbc_path, profile5_crc
from firmware_bridge.profiles.e2e.receiver import E2eReceiver
from firmware_bridge.resources import packaged_path
from firmware_bridge.supervisor import Supervisor, Verdict

C_DIR = packaged_path("c")
VERDICTS = list(Verdict)
TIMEOUT, RAMP, MAX_AGE, LIMIT = 3, 4, 1, 20000

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
    lib.ff_last_cycle.restype = ctypes.c_uint16
    lib.ff_session.restype = ctypes.c_uint8
    lib.ff_crc16.restype = ctypes.c_uint16
    lib.ff_crc16.argtypes = [ctypes.c_char_p, ctypes.c_size_t, ctypes.c_uint16]
    return lib


class CHandler:
    def __init__(self, lib: ctypes.CDLL, data_id: int) -> None:
        self.lib = lib
        self.mem = ctypes.create_string_buffer(lib.ff_handler_size())
        cfg = CConfig(data_id, LIMIT, TIMEOUT, RAMP, MAX_AGE)
        lib.ff_init(self.mem, ctypes.byref(cfg))

    def frame(self, data: bytes) -> Verdict:
        return VERDICTS[self.lib.ff_on_frame(self.mem, data, len(data))]

    def tick(self) -> tuple[int, int, int, int, int]:
        """The output, what DriveStatus carries (cycle, session, state), in-drive or not."""
        out = int(self.lib.ff_tick(self.mem))
        lib, mem = self.lib, self.mem
        status = int(lib.ff_last_cycle(mem)), int(lib.ff_session(mem)), int(lib.ff_state(mem))
        return out, *status, int(lib.ff_in_drive(mem))

    def counts(self) -> list[int]:
        return [int(self.lib.ff_count(self.mem, i)) for i in range(len(VERDICTS))]


class PyHandler:
    def __init__(self, codec: E2eCodec) -> None:
        self.rx = E2eReceiver(codec, Supervisor(LIMIT, TIMEOUT, RAMP), MAX_AGE)

    def frame(self, data: bytes) -> Verdict:
        return self.rx.on_frame(data)

    def tick(self) -> tuple[int, int, int, int, int]:
        out = self.rx.tick()
        return out, self.rx.last_cycle, self.rx.clock.session, self.rx.state, int(self.rx.in_drive)

    def counts(self) -> list[int]:
        return [self.rx.counts.counts[v] for v in VERDICTS]


Event = tuple[str, bytes]


def run_both(lib: ctypes.CDLL, events: list[Event]) -> tuple[list[object], list[object]]:
    codec = E2eCodec()
    c, py = CHandler(lib, codec.command_data_id), PyHandler(codec)
    c_out: list[object] = []
    py_out: list[object] = []
    for kind, data in events:
        if kind == "frame":
            c_out.append(c.frame(data))
            py_out.append(py.frame(data))
        else:
            c_out.append(c.tick())
            py_out.append(py.tick())
    c_out.append(c.counts())
    py_out.append(py.counts())
    return c_out, py_out


@dataclass
class Link:
    """A compensator (session 7) behind a faulty link, and what the drive must never apply.

    The compensator reads the drive's status the instant it is sent (the best case for
    it): after ``tick`` ticks (the last one published: ``tick - 1``) it stamps each
    frame with the next, ``tick``, and asks for the session until granted.
    ``delay`` holds frames for that many ticks; ``stranger`` is a second compensator
    (session 9) that sends well-dated commands all along.
    """

    rng: random.Random
    codec: E2eCodec = field(default_factory=E2eCodec)
    tick: int = 0
    granted: bool = False
    held: dict[int, list[bytes]] = field(default_factory=dict)
    swapped: bytes | None = None  # goes out right after the next frame: reordered
    sent: dict[bytes, int] = field(default_factory=dict)  # command -> its stamp
    events: list[Event] = field(default_factory=list)
    handlers: tuple[CHandler, PyHandler] | None = None  # the drive, both ways, across plays

    def cycle(self, delay: int = 0, stranger: bool = False, fault: float = 0.0) -> None:
        stamp = self.tick
        raw = self.rng.randint(-32767, 32767)
        mode = Mode.COMMAND if self.granted else Mode.REQUEST
        frame = self.codec.encode_command(stamp, raw if self.granted else 0, 7, mode)
        if mode is Mode.COMMAND:
            self.sent[frame] = stamp
        self.events.extend(("frame", old) for old in self.held.pop(self.tick, []))
        if delay:
            self.held.setdefault(self.tick + delay, []).append(frame)
        else:
            self._faulty(frame, fault)
        if self.swapped is not None and self.swapped != frame:
            self.events.append(("frame", self.swapped))
            self.swapped = None
        if stranger:
            self.events.append(("frame", self.codec.encode_command(stamp, 1234, 9, Mode.COMMAND)))
        self.events.append(("tick", b""))
        self.tick += 1

    def _faulty(self, frame: bytes, p: float) -> None:
        r = self.rng.random()
        if r < p / 8:
            return  # dropped
        if r < p / 4 and self.swapped is None:
            self.swapped = frame
            return
        if r < p / 2:
            flipped = bytearray(frame)
            flipped[self.rng.randrange(8)] ^= 1 << self.rng.randrange(8)
            self.events.append(("frame", bytes(flipped)))
            return
        if r < 3 * p / 4 and self.sent:
            self.events.append(("frame", self.rng.choice(list(self.sent))))  # a replay
        self.events.append(("frame", frame))
        if r > 1 - p / 4:
            self.events.append(("frame", frame))  # a duplicate


def play(lib: ctypes.CDLL, link: Link, schedule: list[tuple[int, int, bool, float]]) -> None:
    """Run ``schedule`` (cycles, delay, stranger, fault rate) through both handlers, the
    compensator granted as the drive announces; assert they agree, and the audit."""
    if link.handlers is None:
        link.handlers = CHandler(lib, link.codec.command_data_id), PyHandler(link.codec)
    c, py = link.handlers
    for cycles, delay, stranger, fault in schedule:
        for _ in range(cycles):
            start = len(link.events)
            link.cycle(delay, stranger, fault)
            for kind, data in link.events[start:]:
                if kind == "frame":
                    verdict = c.frame(data)
                    assert verdict is py.frame(data)
                    if verdict is Verdict.ACCEPTED:  # the audit: in its window, ours
                        applied_at = link.tick - 1  # the cycle being played
                        assert 0 <= applied_at - link.sent[data] <= MAX_AGE
                else:
                    status = c.tick()
                    assert status == py.tick()
                    link.granted = status[2] == 7
    assert c.counts() == py.counts()


@pytest.mark.parametrize("seed", range(4))
def test_c_and_python_agree_under_every_frame_fault(lib: ctypes.CDLL, seed: int) -> None:
    link = Link(random.Random(seed))
    play(lib, link, [(400, 0, False, 0.4)])
    verdicts = {v for v in run_both(lib, link.events)[1] if isinstance(v, Verdict)}
    assert verdicts >= {
        Verdict.GRANTED,
        Verdict.ACCEPTED,
        Verdict.CORRUPT,
        Verdict.DUPLICATE,
        Verdict.OUT_OF_ORDER,
    }


@pytest.mark.parametrize("delay", [MAX_AGE + 1, MAX_AGE + 4, 10])
def test_a_sustained_delay_applies_nothing_however_long_it_lasts(
    lib: ctypes.CDLL, delay: int
) -> None:
    """Every frame late by the same amount for 500 cycles (the old counter re-anchored
    after 16 of them): none applied, the output at zero from rx_timeout + ramp on, and
    the stream back only after the delay ends, through a new request."""
    link = Link(random.Random(delay))
    play(lib, link, [(50, 0, False, 0.0), (500, delay, False, 0.0)])
    c = CHandler(lib, link.codec.command_data_id)
    outputs = []
    for kind, data in link.events:
        if kind == "frame":
            c.frame(data)
        else:
            outputs.append(c.tick()[0])
    assert all(out == 0 for out in outputs[50 + TIMEOUT + RAMP + 1 :])
    assert c.counts()[VERDICTS.index(Verdict.STALE)] >= 500 - delay
    before = len(link.events)
    play(lib, link, [(20, 0, False, 0.0)])  # the delay ends: granted again, applied
    resumed = run_both(lib, link.events)[1][before:]
    assert Verdict.GRANTED in resumed and Verdict.ACCEPTED in resumed


def test_a_second_compensator_is_foreign_from_its_first_frame(lib: ctypes.CDLL) -> None:
    link = Link(random.Random(1))
    play(lib, link, [(10, 0, False, 0.0), (200, 0, True, 0.1)])
    verdicts = run_both(lib, link.events)[1]
    assert Verdict.FOREIGN in verdicts


@pytest.mark.parametrize("late_by", range(-1, MAX_AGE + 3))
def test_c_and_python_date_a_frame_alike_at_the_boundary(lib: ctypes.CDLL, late_by: int) -> None:
    """Granted at tick 0, a command for tick 1 arrives ``late_by`` ticks after it:
    applied up to MAX_AGE ticks late (boundary included), stale beyond; a command for
    the tick after next (``late_by`` -1) is early."""
    codec = E2eCodec()
    events: list[Event] = [("frame", codec.encode_command(0, 0, 5, Mode.REQUEST)), ("tick", b"")]
    events += [("tick", b"")] * max(late_by, 0)
    stamp = 1 if late_by >= 0 else 2
    events.append(("frame", codec.encode_command(stamp, 200, 5, Mode.COMMAND)))
    c_out, py_out = run_both(lib, events)
    if late_by < 0:
        expected = Verdict.EARLY
    else:
        expected = Verdict.ACCEPTED if late_by <= MAX_AGE else Verdict.STALE
    assert c_out == py_out and py_out[-2] is expected


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


@settings(max_examples=80, deadline=None)
@given(
    st.lists(
        st.one_of(
            st.just(("tick", 0, 0, 0, 0)),
            st.tuples(
                st.just("frame"),
                st.integers(0, 12),  # stamp, near the ticks the sequence reaches
                st.integers(-300, 300),
                st.integers(1, 3),  # a few sessions contend
                st.sampled_from(list(Mode)),
            ),
        ),
        max_size=80,
    )
)
def test_c_and_python_agree_on_well_formed_frames(
    lib: ctypes.CDLL, steps: list[tuple[str, int, int, int, int]]
) -> None:
    codec = E2eCodec()
    events: list[Event] = [
        ("tick", b"") if kind == "tick" else ("frame", codec.encode_command(s, r, ses, Mode(m)))
        for kind, s, r, ses, m in steps
    ]
    c_out, py_out = run_both(lib, events)
    assert c_out == py_out


@pytest.mark.parametrize(
    "field_bytes", [(4, (-32768).to_bytes(2, "little", signed=True)), (6, b"\x00")]
)
def test_out_of_range_fields_are_corrupt_in_both(
    lib: ctypes.CDLL, field_bytes: tuple[int, bytes]
) -> None:
    """Current -32768 (outside the DBC's [-32767, 32767]), session 0 (every value of the
    2-bit mode is one)."""
    codec = E2eCodec()
    data = bytearray(codec.encode_command(0, 0, 5, Mode.REQUEST))
    offset, value = field_bytes
    data[offset : offset + len(value)] = value
    crc = compute_profile5_crc(bytes(data), codec.command_data_id)
    assert crc is not None
    data[0:2] = crc.to_bytes(2, "little")
    c_out, py_out = run_both(lib, [("frame", bytes(data))])
    assert c_out == py_out and py_out[0] is Verdict.CORRUPT


@settings(max_examples=100, deadline=None)
@given(st.binary(min_size=8, max_size=8), st.integers(0, 0xFFFF))
def test_c_and_python_crc_match_cantools_profile5(
    lib: ctypes.CDLL, payload: bytes, data_id: int
) -> None:
    expected = compute_profile5_crc(payload, data_id)
    assert lib.ff_crc16(payload[2:], 6, data_id) == expected
    assert profile5_crc(payload, data_id) == expected
