"""Profile ``cia402``: a standard servo drive, feedforward in the torque offset 0x60B2.

The drive's EDS (``cia402_drive.eds``, shipped in the package) is the source of
the COB-IDs, the RPDO mapping and the supervision times. 0x60B2 is INTEGER16 in
per mille of the rated torque 0x6076 (rated force for a linear motor); since the
force is the force constant times the current, that is per mille of the rated
current 0x6075, which is how the compensator scales its current.

RPDO1 maps 0x60B2 and, in its third byte, the alive counter 0x2001 (the
compensator's cycle index modulo 256), by which the drive dates each frame (see
:mod:`firmware_bridge.freshness`): a counter-less PDO cannot tell a frame held
up somewhere from a fresh one. RPDO1 has transmission type 1: the drive takes
the RPDOs received since the last SYNC and, at that SYNC, applies the newest
one that is fresh, rejecting older, repeated and stale ones.
"""

from __future__ import annotations

import math
import struct
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import can
import canopen
from canopen.objectdictionary import ObjectDictionary

from gms_comp.errors import BusError

from .freshness import COUNTER_MODULUS, FrameClock
from .resources import packaged_path
from .settings import CanConfig, cycles_within
from .supervisor import RejectCounts, Supervisor, Verdict

TORQUE_OFFSET = 0x60B2
ALIVE_COUNTER = 0x2001  # manufacturer object mapped beside 0x60B2
PRODUCER_HEARTBEAT = 0x1017
RPDO1_COMM, RPDO1_MAP = 0x1400, 0x1600
ABORT_CONNECTION_OPTION = 0x6007
_RPDO = struct.Struct("<hB")  # 0x60B2 INTEGER16, 0x2001 UNSIGNED8
_HEARTBEAT_OPERATIONAL = 0x05
PER_MILLE = 1000

# EMCY error codes (CiA 301 communication errors)
EMCY_RPDO_TIMEOUT = 0x8250
EMCY_HEARTBEAT = 0x8130
EMCY_SYNC_LOST = 0x8100
ABORT_ACTIONS = {0: "no_action", 1: "fault", 2: "disable_voltage", 3: "quick_stop"}


def default_eds_path() -> Path:
    return packaged_path("cia402_drive.eds")


def load_drive_od(node_id: int, eds_path: str | Path | None = None) -> ObjectDictionary:
    path = Path(eds_path) if eds_path is not None else default_eds_path()
    try:
        return canopen.import_od(str(path), node_id)
    except (OSError, KeyError, ValueError) as err:
        raise BusError(f"{path}: not a usable drive EDS ({err})") from err


def od_default(od: ObjectDictionary, index: int, subindex: int | None = None) -> int:
    """Default value of an object of the EDS."""
    entry: Any = od[index] if subindex is None else od[index][subindex]  # type: ignore[index]
    return int(entry.default)


def read_object(node: canopen.LocalNode, index: int, subindex: int | None = None) -> int:
    return int(_sdo_entry(node, index, subindex).raw)


def write_object(node: canopen.LocalNode, index: int, subindex: int | None, value: int) -> None:
    _sdo_entry(node, index, subindex).raw = value


def _sdo_entry(node: canopen.LocalNode, index: int, subindex: int | None) -> Any:
    entry: Any = node.sdo[index]
    return entry if subindex is None else entry[subindex]


class Cia402Codec:
    """Frames of the compensator side, laid out as the drive's EDS says."""

    def __init__(self, cfg: CanConfig, od: ObjectDictionary) -> None:
        mapping = [
            od_default(od, RPDO1_MAP, sub) for sub in range(1, od_default(od, RPDO1_MAP, 0) + 1)
        ]
        wanted = [(TORQUE_OFFSET << 16) | 0x10, (ALIVE_COUNTER << 16) | 0x08]
        if mapping != wanted:
            found = ", ".join(f"0x{m:08X}" for m in mapping)
            raise BusError(
                "RPDO1 must map 0x60B2 (16 bit) then the alive counter 0x2001 (8 bit), "
                f"the EDS maps {found}"
            )
        if od_default(od, RPDO1_COMM, 2) != 1:
            raise BusError("RPDO1 must have transmission type 1 (synchronous, every SYNC)")
        self.rpdo_cob_id = od_default(od, RPDO1_COMM, 1) & 0x7FF
        self.sync_cob_id = od_default(od, 0x1005) & 0x7FF
        self.heartbeat_cob_id = 0x700 + cfg.compensator_node_id
        self.rated_current_A = cfg.rated_current_A
        self.limit_raw = 2**15 - 1

    def to_raw(self, current_A: float) -> int:
        return round(PER_MILLE * current_A / self.rated_current_A)

    def from_raw(self, raw: int) -> float:
        return raw * self.rated_current_A / PER_MILLE

    def rpdo_frame(self, raw: int, counter: int) -> can.Message:
        """RPDO1 with torque offset ``raw`` (per mille) and the cycle's alive counter."""
        return can.Message(
            arbitration_id=self.rpdo_cob_id,
            data=_RPDO.pack(raw, counter % COUNTER_MODULUS),
            is_extended_id=False,
        )

    @staticmethod
    def unpack_rpdo(data: bytes) -> tuple[int, int] | None:
        """``(torque offset, counter)`` of an RPDO1 payload, None if its length is wrong."""
        if len(data) != _RPDO.size:
            return None
        raw, counter = _RPDO.unpack(data)
        return int(raw), int(counter)

    def sync_frame(self) -> can.Message:
        return can.Message(arbitration_id=self.sync_cob_id, data=b"", is_extended_id=False)

    def heartbeat_frame(self) -> can.Message:
        return heartbeat_frame(self.heartbeat_cob_id)


def heartbeat_frame(cob_id: int) -> can.Message:
    """An NMT heartbeat saying "operational"."""
    return can.Message(
        arbitration_id=cob_id, data=bytes([_HEARTBEAT_OPERATIONAL]), is_extended_id=False
    )


class SyncProducer:
    """The NC as SYNC master: one SYNC per cycle on the wall clock.

    Used when the compensator follows SYNC (``sync_master = false``); in a
    real installation the NC or another master produces it.
    """

    def __init__(self, bus: can.BusABC, codec: Cia402Codec, period_s: float) -> None:
        self.bus = bus
        self.frame = codec.sync_frame()
        self.period_s = period_s
        self.sent = 0

    def send(self) -> None:
        self.bus.send(self.frame)
        self.sent += 1

    def run(self, stop: threading.Event, clock: Callable[[], float] = time.perf_counter) -> None:
        """Send SYNC on a fixed grid until ``stop`` is set (call in a thread or process).

        A late wake-up sends one SYNC and rejoins the grid, as a master's timer would.
        """
        next_s = clock()
        while not stop.is_set():
            remaining = next_s - clock()
            if remaining > 0:
                time.sleep(remaining)
            self.send()
            missed = max(0, math.floor((clock() - next_s) / self.period_s))
            next_s += (1 + missed) * self.period_s


def configure_drive(node: canopen.LocalNode, cfg: CanConfig) -> None:
    """Write the supervision times of ``cfg`` into the drive's object dictionary,
    as an NC would by SDO at start-up."""
    write_object(node, 0x1006, None, round(cfg.cycle_period_s * 1e6))
    write_object(node, RPDO1_COMM, 5, max(1, round(cfg.rx_timeout_s * 1e3)))
    consumer_ms = max(1, round(1.5 * cfg.heartbeat_period_s * 1e3))
    write_object(node, 0x1016, 1, (cfg.compensator_node_id << 16) | consumer_ms)
    write_object(node, PRODUCER_HEARTBEAT, None, max(1, round(cfg.heartbeat_period_s * 1e3)))
    write_object(node, 0x6075, None, round(cfg.rated_current_A * 1e3))


class Cia402Receiver:
    """The drive side: buffer RPDOs until SYNC, supervise RPDO, SYNC and heartbeat."""

    def __init__(
        self,
        node: canopen.LocalNode,
        codec: Cia402Codec,
        cfg: CanConfig,
        limit_raw: int,
    ) -> None:
        self.node = node
        self.codec = codec
        self.cycle_period_s = cfg.cycle_period_s
        self.counts = RejectCounts()
        event_timer_s = read_object(node, RPDO1_COMM, 5) * 1e-3
        self.supervisor = Supervisor(
            limit_raw, cycles_within(event_timer_s, cfg.cycle_period_s), cfg.ramp_cycles
        )
        self.sync_timeout_s = 1.5 * read_object(node, 0x1006) * 1e-6
        consumer = read_object(node, 0x1016, 1)
        self.heartbeat_producer = 0x700 + ((consumer >> 16) & 0x7F)
        self.heartbeat_timeout_s = (consumer & 0xFFFF) * 1e-3
        self.clock = FrameClock(cfg.max_frame_age_cycles)
        self.window: list[bytes] = []
        self.fresh: tuple[int, bytes] | None = None
        self.applied_data: bytes | None = None
        self.last_sync_s: float | None = None
        self.last_heartbeat_s: float | None = None
        self.active_faults: set[int] = set()
        self.emcy_sent: list[int] = []
        self.heartbeats_sent = 0
        self._next_heartbeat_s: float | None = None

    def on_message(self, msg: can.Message, now_s: float) -> None:
        cob_id = msg.arbitration_id
        if msg.is_error_frame:
            self.counts.add(Verdict.CORRUPT)  # the controller's CRC caught a damaged frame
        elif cob_id == self.codec.rpdo_cob_id:
            if self.codec.unpack_rpdo(bytes(msg.data)) is not None:
                self.window.append(bytes(msg.data))
            else:
                self.counts.add(Verdict.CORRUPT)
        elif cob_id == self.codec.sync_cob_id:
            self.last_sync_s = now_s
            self._close_window()
        elif cob_id == self.heartbeat_producer:
            self.last_heartbeat_s = now_s
        else:  # SDO, NMT: the canopen LocalNode answers
            self.node.network.notify(cob_id, msg.data, msg.timestamp)

    def _close_window(self) -> None:
        """At SYNC: judge the window's RPDOs in arrival order; the newest fresh one wins.

        Frames are dated in drive cycles, which run on time whether SYNC comes
        or not; the compensator numbers its frames by the same time slots (as
        SYNC follower: the slot of the SYNC it answers).
        """
        window, self.window = self.window, []
        for data in window:
            unpacked = self.codec.unpack_rpdo(data)
            assert unpacked is not None  # checked on arrival
            raw, counter = unpacked
            verdict = self.clock.judge(counter)
            self.counts.add(verdict)
            if verdict is Verdict.ACCEPTED:
                self.fresh = (raw, data)

    def tick(self, now_s: float) -> int:
        """One drive cycle at time ``now_s``; returns the applied 0x60B2 value."""
        self._supervise(now_s)
        # a lost SYNC or heartbeat voids the link; a lost RPDO ends with the next one
        fresh = None if self.active_faults - {EMCY_RPDO_TIMEOUT} else self.fresh
        self.fresh = None
        was_lost = self.supervisor.link_lost
        out = self.supervisor.tick(fresh[0] if fresh else None)
        self.applied_data = fresh[1] if fresh else None
        self.clock.tick()
        if self.supervisor.link_lost and not was_lost:
            self.clock.link_lost()
            self._raise_fault(EMCY_RPDO_TIMEOUT)
        elif fresh:
            self.active_faults.discard(EMCY_RPDO_TIMEOUT)
        write_object(self.node, TORQUE_OFFSET, None, out)
        self._produce_heartbeat(now_s)
        return out

    def _produce_heartbeat(self, now_s: float) -> None:
        """The drive's own heartbeat, every 0x1017 ms (0 disables it), read each time
        because the NC may change it by SDO."""
        period_s = read_object(self.node, PRODUCER_HEARTBEAT) * 1e-3
        if period_s <= 0:
            self._next_heartbeat_s = None
            return
        if self._next_heartbeat_s is None or now_s >= self._next_heartbeat_s:
            cob_id = 0x700 + int(self.node.id or 0)
            self.node.network.send_message(cob_id, bytes([_HEARTBEAT_OPERATIONAL]))
            self.heartbeats_sent += 1
            self._next_heartbeat_s = now_s + period_s - 1e-9

    def _supervise(self, now_s: float) -> None:
        if self._overdue(self.last_sync_s, self.sync_timeout_s, now_s):
            self._raise_fault(EMCY_SYNC_LOST)
            # the SYNC these RPDOs waited for did not come in time: stale once it does
            for _ in self.window:
                self.counts.add(Verdict.STALE)
            self.window = []
        else:
            self.active_faults.discard(EMCY_SYNC_LOST)
        if self._overdue(self.last_heartbeat_s, self.heartbeat_timeout_s, now_s):
            self._raise_fault(EMCY_HEARTBEAT)
        else:
            self.active_faults.discard(EMCY_HEARTBEAT)

    @staticmethod
    def _overdue(last_s: float | None, timeout_s: float, now_s: float) -> bool:
        # before the first message there is nothing to supervise yet
        return last_s is not None and now_s - last_s > timeout_s

    def _raise_fault(self, code: int) -> None:
        if code in self.active_faults:
            return
        self.active_faults.add(code)
        self.emcy_sent.append(code)
        self.node.emcy.send(code, register=0x11)  # error register: generic + communication

    @property
    def abort_action(self) -> str:
        """Drive reaction to a lost link, from 0x6007 (the offset ramps to zero in any case)."""
        return ABORT_ACTIONS.get(read_object(self.node, ABORT_CONNECTION_OPTION), "manufacturer")

    @property
    def state(self) -> str:
        if self.active_faults or self.supervisor.link_lost:
            return self.abort_action if self.active_faults else "waiting"
        return "operation_enabled"
