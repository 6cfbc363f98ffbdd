"""The drive side of cia402: buffer RPDOs until SYNC, date them, supervise RPDO, SYNC, heartbeat."""

from __future__ import annotations

import can
import canopen

from firmware_bridge.freshness import (
    MAX_IN_DRIVE_LEVEL_RAW,
    DriveClock,
    Mode,
    session_timeout_cycles,
)
from firmware_bridge.profiles.cia402.codec import (
    ABORT_ACTIONS,
    ABORT_CONNECTION_OPTION,
    EMCY_HEARTBEAT,
    EMCY_RPDO_TIMEOUT,
    EMCY_SYNC_LOST,
    FF_RPDO,
    HEARTBEAT_OPERATIONAL,
    HEARTBEAT_PRE_OPERATIONAL,
    NMT_ENTER_PRE_OPERATIONAL,
    NMT_START,
    NMT_STOP,
    PRODUCER_HEARTBEAT,
    TORQUE_OFFSET,
    Cia402Codec,
    read_object,
    write_object,
)
from firmware_bridge.settings import CanConfig, cycles_within
from firmware_bridge.supervisor import RejectCounts, Supervisor, Verdict


class Cia402Receiver:
    """The drive side: buffer RPDOs until SYNC, supervise RPDO, SYNC and heartbeat.

    The drive cycle is its own count of ticks (:class:`~firmware_bridge.freshness.DriveClock`
    advances after each :meth:`tick`, SYNC or not: a lost SYNC does not stop the drive's
    clock). At a SYNC the RPDOs received since the last one are judged in arrival order
    against the cycle of the next tick, which applies the newest accepted command.
    """

    def __init__(
        self,
        node: canopen.LocalNode,
        codec: Cia402Codec,
        cfg: CanConfig,
        limit_raw: int,
    ) -> None:
        self.node = node
        self.codec = codec
        self.counts = RejectCounts()
        event_timer_s = read_object(node, FF_RPDO.comm, 5) * 1e-3
        self.supervisor = Supervisor(
            limit_raw, cycles_within(event_timer_s, cfg.cycle_period_s), cfg.ramp_cycles
        )
        self.sync_timeout_s = 1.5 * read_object(node, 0x1006) * 1e-6
        consumer = read_object(node, 0x1016, 1)
        self.heartbeat_producer = 0x700 + ((consumer >> 16) & 0x7F)
        self.heartbeat_timeout_s = (consumer & 0xFFFF) * 1e-3
        self.clock = DriveClock(
            cfg.max_frame_age_cycles, session_timeout_cycles(self.supervisor.timeout_cycles)
        )
        self.window: list[bytes] = []  # RPDOs since the last SYNC
        self.fresh: tuple[int, bytes, bool] | None = None  # value, frame, in-drive level?
        self.in_drive = False  # the value applied is the level of the drive's own observer
        self.applied_data: bytes | None = None
        self.last_sync_s: float | None = None
        self.last_heartbeat_s: float | None = None
        self.active_faults: set[int] = set()
        self.emcy_sent: list[int] = []
        self.heartbeats_sent = 0
        self._next_heartbeat_s: float | None = None
        self.out_of_operation = False  # taken out of operation by NMT: no PDO, no supervision
        self.last_cycle = 0  # the tick just run

    def on_message(self, msg: can.Message, now_s: float) -> bool:
        """Take one frame received at ``now_s``; whether it was a SYNC (the PDOs are due)."""
        cob_id = msg.arbitration_id
        if msg.is_error_frame:
            self.counts.add(Verdict.CORRUPT)  # the controller's CRC caught a damaged frame
        elif cob_id == self.codec.rpdo_cob_id:
            if not self.out_of_operation:
                self.window.append(bytes(msg.data))
        elif cob_id == self.codec.sync_cob_id:
            self.last_sync_s = now_s
            if not self.out_of_operation:
                self._close_window()
                return True
        elif cob_id == self.heartbeat_producer:
            self.last_heartbeat_s = now_s
        elif cob_id == 0x000 and len(msg.data) == 2:
            self._on_nmt(msg.data[0], msg.data[1])
            self.node.network.notify(cob_id, msg.data, msg.timestamp)
        else:  # SDO, NMT: the canopen LocalNode answers
            self.node.network.notify(cob_id, msg.data, msg.timestamp)
        return False

    def _close_window(self) -> None:
        """At SYNC: the RPDOs since the last one judged in arrival order, for the next
        tick; the newest accepted command wins."""
        window, self.window = self.window, []
        for data in window:
            command = self.codec.unpack_rpdo(data)
            if command is None:
                self.counts.add(Verdict.CORRUPT)
                continue
            verdict = self.clock.judge(command.cycle, command.session, command.mode)
            self.counts.add(verdict)
            if verdict is Verdict.ACCEPTED:
                self.fresh = (command.raw, data, command.mode is Mode.IN_DRIVE)
            elif verdict is Verdict.RELEASED:  # a clean stop: no timeout, no fault follows
                self.fresh = None
                self.supervisor.end()
                self.last_heartbeat_s = None
                self.active_faults.discard(EMCY_RPDO_TIMEOUT)

    def _on_nmt(self, command: int, node_id: int) -> None:
        """An orderly stop (pre-operational, stopped) ends PDOs, sessions and supervision."""
        if node_id not in (0, self.node.id):
            return
        if command in (NMT_ENTER_PRE_OPERATIONAL, NMT_STOP):
            self.out_of_operation = True
            self.active_faults.clear()
            self.window = []
            self.clock.release()
            self.supervisor.end()
        elif command == NMT_START:
            self.out_of_operation = False
            self.last_sync_s = self.last_heartbeat_s = None

    def tick(self, now_s: float) -> int:
        """One drive cycle at time ``now_s``; returns the applied 0x60B2 value."""
        if self.out_of_operation:  # no PDO applied, nothing supervised, output to zero
            self.fresh = self.applied_data = None
            out = self.supervisor.tick(None)
            self.last_cycle = self.clock.cycle
            self.clock.advance()
            write_object(self.node, TORQUE_OFFSET, None, out)
            self._produce_heartbeat(now_s)
            return out
        self._supervise(now_s)
        # a lost SYNC or heartbeat voids the link; a lost RPDO ends with the next one
        fresh = None if self.active_faults - {EMCY_RPDO_TIMEOUT} else self.fresh
        self.fresh = None
        was_lost = self.supervisor.link_lost
        # an in-drive level is no current: saturated at MAX_LEVEL, ramped to zero alike
        limit = MAX_IN_DRIVE_LEVEL_RAW if fresh and fresh[2] else None
        out = self.supervisor.tick(fresh[0] if fresh else None, limit)
        self.applied_data = fresh[1] if fresh else None
        if fresh:
            self.in_drive = fresh[2]
        if self.supervisor.link_lost and not was_lost:
            self.raise_fault(EMCY_RPDO_TIMEOUT)
        elif fresh:
            self.active_faults.discard(EMCY_RPDO_TIMEOUT)
        self.last_cycle = self.clock.cycle
        self.clock.advance()
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
            state = HEARTBEAT_PRE_OPERATIONAL if self.out_of_operation else HEARTBEAT_OPERATIONAL
            self.node.network.send_message(cob_id, bytes([state]))
            self.heartbeats_sent += 1
            self._next_heartbeat_s = now_s + period_s - 1e-9

    def _supervise(self, now_s: float) -> None:
        if self._overdue(self.last_sync_s, self.sync_timeout_s, now_s):
            self.raise_fault(EMCY_SYNC_LOST)
            # the SYNC these RPDOs waited for did not come in time: stale once it does
            for _ in self.window:
                self.counts.add(Verdict.STALE)
            self.window = []
        else:
            self.active_faults.discard(EMCY_SYNC_LOST)
        if self._overdue(self.last_heartbeat_s, self.heartbeat_timeout_s, now_s):
            self.raise_fault(EMCY_HEARTBEAT)
        else:
            self.active_faults.discard(EMCY_HEARTBEAT)

    @staticmethod
    def _overdue(last_s: float | None, timeout_s: float, now_s: float) -> bool:
        # before the first message there is nothing to supervise yet
        return last_s is not None and now_s - last_s > timeout_s

    def raise_fault(self, code: int) -> None:
        """Send EMCY ``code`` once, until the fault clears."""
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
        """``operation_enabled``, ``waiting`` (no feedforward yet or link lost without a
        fault), ``pre_operational`` (stopped in order by NMT) or the 0x6007 reaction."""
        if self.out_of_operation:
            return "pre_operational"
        if self.active_faults or self.supervisor.link_lost:
            return self.abort_action if self.active_faults else "waiting"
        return "operation_enabled"
