"""The compensator side of cia402: RPDO1 each cycle, SYNC as master, its heartbeat."""

from __future__ import annotations

from typing import Any

import can

from firmware_bridge.profiles.base import SyncCounter
from firmware_bridge.profiles.cia402.codec import Cia402Codec, load_drive_od
from firmware_bridge.settings import CanConfig

_BOOTUP = b"\x00"  # NMT boot-up: the same COB-ID as the heartbeat, not one


class Cia402Tx:
    """Frames the compensator sends to a CiA 402 drive, and what it hears back.

    Parameters
    ----------
    cfg
        The ``[can]`` section.
    """

    def __init__(self, cfg: CanConfig) -> None:
        self.cfg = cfg
        self.codec = Cia402Codec(cfg, load_drive_od(cfg.drive_node_id))
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
        self.emcy_received: list[int] = []
        self.drive_heartbeats = 0
        self.sync: SyncCounter | None = SyncCounter()  # SYNCs on the bus, whoever produced them

    def to_raw(self, current_A: float) -> int:
        """Current in A -> per mille of the rated current."""
        return self.codec.to_raw(current_A)

    def frames(self, cycle: int, raw: int) -> tuple[can.Message, list[can.Message]]:
        """RPDO1 of ``cycle``; then SYNC (as master) and, when due, the heartbeat."""
        extra = [self.codec.sync_frame()] if self.cfg.sync_master else []
        if cycle % self.heartbeat_cycles == 0:
            extra.append(self.codec.heartbeat_frame())
        return self.codec.rpdo_frame(raw, cycle), extra

    def traffic(self) -> list[tuple[int, float]]:
        """RPDO1 (3 bytes) and SYNC every cycle, the heartbeat every heartbeat period.

        SYNC is on the bus whoever produces it: without data from this compensator,
        with the one-byte SYNC counter from the NC (:class:`~.nc.SyncProducer`).
        """
        rate = 1.0 / self.cfg.cycle_period_s
        sync_bytes = 0 if self.cfg.sync_master else 1
        return [(3, rate), (sync_bytes, rate), (1, 1.0 / self.cfg.heartbeat_period_s)]

    def on_reply(self, msg: can.Message) -> None:
        """Count SYNCs, the drive's EMCYs and heartbeats."""
        cob_id = msg.arbitration_id
        if cob_id == self.codec.sync_cob_id:
            assert self.sync is not None
            self.sync.saw(msg.timestamp, bytes(msg.data))
        elif cob_id == 0x80 + self.cfg.drive_node_id and len(msg.data) >= 2:
            self.emcy_received.append(int.from_bytes(msg.data[:2], "little"))
        elif cob_id == 0x700 + self.cfg.drive_node_id and msg.data[:1] != _BOOTUP:
            self.drive_heartbeats += 1

    def stop_frames(self) -> tuple[list[can.Message], str]:
        """As SYNC master: NMT pre-operational to the drive, so silence is no fault.

        Following an NC's SYNC, the NC owns the drive's state: nothing is sent.
        """
        if self.follows_sync:
            return [], "the NC owns the drive's state: the drive sees the RPDOs stop"
        return [self.codec.leave_operation_frame()], (
            f"NMT pre-operational sent to drive node {self.cfg.drive_node_id}: "
            "PDOs and their supervision end without a fault"
        )

    def report(self) -> dict[str, Any]:
        """Who produced SYNC, and the drive heartbeats heard."""
        return {
            "sync_source": "nc" if self.follows_sync else "compensator",
            "drive_heartbeats_received": self.drive_heartbeats,
        }
