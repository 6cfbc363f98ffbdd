"""Fault injection on the sending side of any python-can bus.

A fault spec reads ``KIND[=CYCLES][:PROBABILITY][@START-END]``: ``drop:0.05`` drops
5 % of the feedforward frames, ``drop@0.2-0.25`` drops all of them for 50 ms (link
loss), ``delay=5@0.2-0.4`` holds every frame for 5 cycles for 0.2 s (a sustained
delay; ``CYCLES`` is for ``delay`` only, 2 by default), ``stall@0.3-0.32`` stalls the
control loop, ``bus_error@0.4-0.45`` makes every send fail (bus off). Frame faults
touch only the feedforward frames. Times are bounded by :data:`MAX_FAULT_TIME_S`,
delays by :data:`MAX_DELAY_CYCLES`.

``corrupt`` flips one payload bit. Where the frame carries its own CRC (e2e)
the damaged frame is delivered, as from a faulty gateway or memory; where it
does not (cia402), the flip is taken to happen on the wire, where the receiving
controller's CRC-15 discards the frame: the receiver gets an error frame.
"""

from __future__ import annotations

import bisect
import math
import random
import re
import time
from dataclasses import dataclass, field
from typing import Literal, get_args

import can

from gms_comp.errors import BusError

FaultKind = Literal["drop", "delay", "duplicate", "reorder", "corrupt", "stall", "bus_error"]
FAULT_KINDS: tuple[str, ...] = get_args(FaultKind)
DELAY_CYCLES = 2
MAX_DELAY_CYCLES = 1000
"""A frame held longer than this is a lost link, not a delay."""
MAX_FAULT_TIME_S = 3600.0
"""A fault window ends within the longest stream (``stream --duration``)."""
_NUMBER = r"[0-9][0-9.eE+-]{0,15}"
_SPEC = re.compile(
    rf"^(?P<kind>[a-z_]{{1,16}})(?:=(?P<cycles>[0-9]{{1,4}}))?(?::(?P<p>{_NUMBER}))?"
    rf"(?:@(?P<start>{_NUMBER})-(?P<end>{_NUMBER}))?$"
)


@dataclass(frozen=True)
class Fault:
    """A fault of one kind, hitting with ``probability`` while ``start_s <= t < end_s``."""

    kind: FaultKind
    probability: float = 1.0
    start_s: float = 0.0
    end_s: float = math.inf
    cycles: int = DELAY_CYCLES  # how long a delay holds a frame

    def active(self, now_s: float) -> bool:
        """Whether the fault is active at ``now_s``."""
        return self.start_s <= now_s < self.end_s


def parse_fault(text: str) -> Fault:
    """Parse one ``KIND[=CYCLES][:PROBABILITY][@START-END]`` spec (see the module docstring).

    Raises
    ------
    BusError
        One line naming the spec and what is wrong with it.
    """
    shown = repr(text[:60] + ("..." if len(text) > 60 else ""))
    m = _SPEC.match(text.strip()) if len(text) <= 80 else None
    if m is None or m["kind"] not in FAULT_KINDS:
        raise BusError(
            f"bad fault spec {shown}: expected KIND[=CYCLES][:PROBABILITY][@START-END] "
            f"with KIND one of {', '.join(FAULT_KINDS)}"
        )
    try:
        p = float(m["p"]) if m["p"] else 1.0
        start = float(m["start"]) if m["start"] else 0.0
        end = float(m["end"]) if m["end"] else math.inf
    except ValueError:
        raise BusError(f"bad fault spec {shown}: numbers expected") from None
    if not 0.0 <= p <= 1.0 or not 0.0 <= start < end:
        raise BusError(f"bad fault spec {shown}: need 0 <= PROBABILITY <= 1, 0 <= START < END")
    if start > MAX_FAULT_TIME_S or (math.isfinite(end) and end > MAX_FAULT_TIME_S):
        raise BusError(f"bad fault spec {shown}: START and END must be <= {MAX_FAULT_TIME_S:g} s")
    cycles = DELAY_CYCLES
    if m["cycles"] is not None:
        cycles = int(m["cycles"])
        if m["kind"] != "delay" or not 1 <= cycles <= MAX_DELAY_CYCLES:
            raise BusError(
                f"bad fault spec {shown}: =CYCLES is for delay only, 1..{MAX_DELAY_CYCLES}"
            )
    return Fault(m["kind"], p, start, end, cycles)  # type: ignore[arg-type]


@dataclass
class FaultyBus:
    """Sends through ``bus``, damaging frames with ids in ``target_ids`` per ``faults``."""

    bus: can.BusABC
    faults: tuple[Fault, ...]
    target_ids: frozenset[int]
    self_checked: bool  # frames carry their own CRC (see module docstring)
    seed: int = 0
    now_s: float = 0.0
    cycle: int = 0
    injected: dict[str, int] = field(default_factory=dict)
    _held: list[tuple[int, can.Message]] = field(default_factory=list)
    _reordered: can.Message | None = None

    def __post_init__(self) -> None:
        self._rng = random.Random(self.seed)

    def begin_cycle(self, cycle: int, now_s: float) -> None:
        """Start control cycle ``cycle``: release delayed frames that are due."""
        self.cycle, self.now_s = cycle, now_s
        due = [m for c, m in self._held if c <= cycle]
        self._held = [(c, m) for c, m in self._held if c > cycle]
        for msg in due:
            self._send(msg)

    def _hits(self, kind: str) -> bool:
        return any(
            f.kind == kind and f.active(self.now_s) and self._rng.random() < f.probability
            for f in self.faults
        )

    def _delay(self) -> Fault | None:
        """The delay fault that hits this frame, if any."""
        for f in self.faults:
            if f.kind == "delay" and f.active(self.now_s) and self._rng.random() < f.probability:
                return f
        return None

    def _count(self, kind: str) -> None:
        self.injected[kind] = self.injected.get(kind, 0) + 1

    def stall_end(self, now_s: float) -> float | None:
        """End of the controller stall injected at ``now_s``, if any."""
        ends = [f.end_s for f in self.faults if f.kind == "stall" and f.active(now_s)]
        return max(ends, default=None)

    def stalled(self) -> bool:
        """Whether the control loop is stalled in the current cycle."""
        return self.stall_end(self.now_s) is not None

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Send ``msg``, damaged, delayed or dropped as the active faults say."""
        if self._hits("bus_error"):
            self._count("bus_error")
            raise can.CanOperationError("bus off (injected fault)")
        if msg.arbitration_id not in self.target_ids:
            self._send(msg)
            return
        self._send_target(msg)
        if self._reordered is not None and self._reordered is not msg:
            held, self._reordered = self._reordered, None
            self._send(held)

    def _send_target(self, msg: can.Message) -> None:
        if self._hits("drop"):
            self._count("drop")
            return
        delay = self._delay()
        if delay is not None:
            self._count("delay")
            self._held.append((self.cycle + delay.cycles, msg))
            return
        if self._reordered is None and self._hits("reorder"):
            self._count("reorder")
            self._reordered = msg  # goes out right after the next feedforward frame
            return
        if self._hits("corrupt"):
            self._count("corrupt")
            msg = self._corrupted(msg)
        self._send(msg)
        if self._hits("duplicate"):
            self._count("duplicate")
            self._send(msg)

    def _corrupted(self, msg: can.Message) -> can.Message:
        data = bytearray(msg.data)
        bit = self._rng.randrange(8 * len(data))
        data[bit // 8] ^= 1 << (bit % 8)
        return can.Message(
            arbitration_id=msg.arbitration_id,
            data=bytes(data),
            is_extended_id=msg.is_extended_id,
            is_error_frame=not self.self_checked,
        )

    def _send(self, msg: can.Message) -> None:
        self.bus.send(msg)

    def recv(self, timeout: float | None = None) -> can.Message | None:
        """Receive from the underlying bus (faults act on sending only)."""
        return self.bus.recv(timeout)


@dataclass
class FaultyReceiver:
    """Receives through ``bus``, dropping or delaying frames with ids in ``target_ids`` as
    the ``drop`` and ``delay`` faults say (a lossy link in front of a listener: a recorder).

    Fault windows count from the first call; a delay holds a frame ``cycles`` x
    ``period_s`` by its timestamp, then hands it on.
    """

    bus: can.BusABC
    faults: tuple[Fault, ...]
    target_ids: frozenset[int]
    period_s: float
    seed: int = 0
    injected: dict[str, int] = field(default_factory=dict)
    _held: list[tuple[float, can.Message]] = field(default_factory=list)
    _t0: float | None = None

    def __post_init__(self) -> None:
        self._rng = random.Random(self.seed)

    def recv(self, timeout: float | None = None) -> can.Message | None:
        """The next frame that got through (a held one once it is due), or None (also when
        the frame received was dropped or held: call again)."""
        msg = self.bus.recv(timeout)
        now = time.time() if msg is None else msg.timestamp
        if msg is not None and self._t0 is None:
            self._t0 = msg.timestamp
        if msg is not None and msg.arbitration_id in self.target_ids:
            msg = self._through(msg)
        if self._held and self._held[0][0] <= now:
            if msg is not None:  # the held frame goes first, this one right after
                bisect.insort(self._held, (now, msg), key=lambda held: held[0])
            return self._held.pop(0)[1]
        return msg

    def _through(self, msg: can.Message) -> can.Message | None:
        assert self._t0 is not None
        now = msg.timestamp - self._t0
        for f in self.faults:
            if not f.active(now) or self._rng.random() >= f.probability:
                continue
            if f.kind == "drop":
                self.injected["drop"] = self.injected.get("drop", 0) + 1
                return None
            if f.kind == "delay":
                self.injected["delay"] = self.injected.get("delay", 0) + 1
                release = msg.timestamp + f.cycles * self.period_s
                bisect.insort(self._held, (release, msg), key=lambda held: held[0])
                return None
        return msg
