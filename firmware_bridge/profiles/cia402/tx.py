"""The compensator side of cia402: RPDO2 each cycle, SYNC as master, its heartbeat."""

from __future__ import annotations

from typing import Any

import can

from firmware_bridge.freshness import DriveTime, Mode
from firmware_bridge.profiles.base import SYNC_COUNTER_OVERFLOW, Claim, SyncCounter, sync_slot
from firmware_bridge.profiles.cia402.codec import (
    FF_RPDO,
    POSITION_UNIT_PM,
    STATUS_TPDO,
    Cia402Codec,
    load_drive_od,
    od_default,
)
from firmware_bridge.profiles.cia402.motion import PICOMETRE, NcProgram, Observed
from firmware_bridge.profiles.cia402.recorder import Recorder
from firmware_bridge.settings import CanConfig

_BOOTUP = b"\x00"  # NMT boot-up: the same COB-ID as the heartbeat, not one


class Cia402Tx:
    """Frames the compensator sends to a CiA 402 drive, and what it hears back.

    Parameters
    ----------
    cfg
        The ``[can]`` section.

    The drive's clock is its own tick count, published in TPDO1 at the tick after a
    SYNC: a frame is stamped by :class:`~firmware_bridge.freshness.DriveTime` from it,
    one cycle later as a SYNC follower (the RPDO waits for the next SYNC).
    """

    def __init__(self, cfg: CanConfig) -> None:
        self.cfg = cfg
        od = load_drive_od(cfg.drive_node_id)
        self.codec = Cia402Codec(cfg, od)
        unit_m = od_default(od, POSITION_UNIT_PM) * PICOMETRE
        self.observed = Observed(unit_m, cfg.rated_current_A)  # the motion on the bus
        self.program: NcProgram | None = None  # the NC's part, when this side drives the axis
        self.recorder: Recorder | None = None  # a recording of the axis, per SYNC
        self._slots: tuple[int, int | None, float] | None = None  # last slot, counter, first
        self.target_ids = frozenset({self.codec.rpdo_cob_id})
        # our heartbeat's node id, and SYNC when we produce it, are ours alone too
        own = {self.codec.rpdo_cob_id, self.codec.heartbeat_cob_id}
        if cfg.sync_master:
            own.add(self.codec.sync_cob_id)
        self.exclusive_ids = frozenset(own)
        self.self_checked = False
        self.follows_sync = not cfg.sync_master
        self.limit_raw = min(self.codec.limit_raw, self.codec.to_raw(cfg.max_current_A))
        self.heartbeat_cycles = max(1, round(cfg.heartbeat_period_s / cfg.cycle_period_s))
        horizon = cfg.timeout_cycles + cfg.status_every_cycles
        self.claim = Claim(DriveTime(cfg.cycle_period_s, horizon, int(self.follows_sync)))
        self.emcy_received: list[int] = []
        self.drive_heartbeats = 0
        self.sync: SyncCounter | None = SyncCounter()  # SYNCs on the bus, whoever produced them

    def to_raw(self, current_A: float) -> int:
        """Current in A -> per mille of the rated current."""
        return self.codec.to_raw(current_A)

    def feedforward(self, mode: Mode, raw: int, now_s: float) -> can.Message | None:
        """RPDO2 stamped with the SYNC it applies at; None before the drive's first TPDO1."""
        stamp = self.claim.time.stamp(now_s)
        if stamp is None:
            return None
        return self.codec.rpdo_frame(raw, stamp, self.claim.session, mode)

    def extra(self, cycle: int) -> list[can.Message]:
        """After the feedforward RPDO: as SYNC master, the NC's RPDO1 when this side
        drives the axis, then SYNC; the heartbeat when due."""
        frames = []
        if self.cfg.sync_master:
            target = None
            if self.program is not None:
                self.program.start_at(self.observed.position_m)
                rpdo = self.program.rpdo(self.codec, self.observed.state)
                if rpdo is not None:
                    frames.append(rpdo)
                    self.observed.take(self.codec, rpdo)
                    target = self.observed.target_m
            counter = cycle % SYNC_COUNTER_OVERFLOW + 1  # CiA 301: 1..240
            frames.append(self.codec.sync_frame(counter))
            if self.recorder is not None:
                self.recorder.sync(cycle, counter, target)
        if cycle % self.heartbeat_cycles == 0:
            frames.append(self.codec.heartbeat_frame())
        return frames

    def traffic(self) -> list[tuple[int, float]]:
        """RPDO2 and SYNC every cycle, the drive's TPDO1 every ``status_every_cycles``, the
        heartbeat.

        SYNC is on the bus whoever produces it: without data from this compensator,
        with the one-byte SYNC counter from the NC (:class:`~.nc.SyncProducer`).
        """
        rate = 1.0 / self.cfg.cycle_period_s
        sync_bytes = 1  # with the CiA 301 SYNC counter, whoever produces it
        return [
            (FF_RPDO.size, rate),
            (sync_bytes, rate),
            (STATUS_TPDO.size, rate / self.cfg.status_every_cycles),
            (1, 1.0 / self.cfg.heartbeat_period_s),
        ]

    def on_reply(self, msg: can.Message, now_s: float) -> None:
        """The drive's TPDO1 (its cycle and session); the motion seen (the NC's RPDO1, the
        TPDOs) and the recording; SYNCs, EMCYs and heartbeats counted."""
        cob_id = msg.arbitration_id
        self.observed.take(self.codec, msg)
        if self.recorder is not None:
            self.recorder.frame(msg)
        if cob_id == self.codec.status_cob_id:
            report = self.codec.unpack_status(bytes(msg.data))
            if report is not None:
                self.claim.time.observe(report.cycle, report.session, now_s)
        elif cob_id == self.codec.sync_cob_id:
            assert self.sync is not None
            self.sync.saw(msg.timestamp, bytes(msg.data))
            if self.recorder is not None:
                self.recorder.sync(self._follower_slot(), self.sync.last_counter or 0)
        elif cob_id == 0x80 + self.cfg.drive_node_id and len(msg.data) >= 2:
            self.emcy_received.append(int.from_bytes(msg.data[:2], "little"))
        elif cob_id == 0x700 + self.cfg.drive_node_id and msg.data[:1] != _BOOTUP:
            self.drive_heartbeats += 1

    def _follower_slot(self) -> int:
        """The time slot of the SYNC just seen: by the NC's SYNC counter, whole wraps by
        time (:func:`~firmware_bridge.profiles.base.sync_slot`)."""
        assert self.sync is not None
        if self._slots is None:
            self._slots = (0, self.sync.last_counter, self.sync.last_s)
            return 0
        previous, counter, first_s = self._slots
        by_time = round((self.sync.last_s - first_s) / self.cfg.cycle_period_s)
        slot = sync_slot(previous, counter, self.sync.last_counter, by_time)
        self._slots = (slot, self.sync.last_counter, first_s)
        return slot

    def stop_frames(self) -> tuple[list[can.Message], str]:
        """As SYNC master: NMT pre-operational to the drive, so silence is no fault.

        Following an NC's SYNC, the NC owns the drive's state: the release ends the
        stream, nothing more is sent.
        """
        if self.follows_sync:
            return [], "session released; the NC owns the drive's state"
        frames = []
        if self.program is not None and self.program.phase.value in ("enabling", "moving"):
            self.program.stop()  # stopped early: the axis is disabled first
            rpdo = self.program.rpdo(self.codec, self.observed.state)
            frames += [*([rpdo] if rpdo is not None else []), self.codec.sync_frame()]
        return [*frames, self.codec.leave_operation_frame()], (
            f"session released, NMT pre-operational sent to drive node "
            f"{self.cfg.drive_node_id}: PDOs and their supervision end without a fault"
        )

    def report(self) -> dict[str, Any]:
        """Who produced SYNC, and the drive heartbeats heard."""
        return {
            "sync_source": "nc" if self.follows_sync else "compensator",
            "drive_heartbeats_received": self.drive_heartbeats,
        }
