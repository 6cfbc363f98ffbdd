"""The compensator side of e2e: one FfCommand per cycle; the drive's status frame back."""

from __future__ import annotations

from typing import Any

import can

from firmware_bridge.profiles.base import SyncCounter
from firmware_bridge.profiles.e2e.codec import DriveStatus, E2eCodec
from firmware_bridge.settings import CanConfig


class E2eTx:
    """Frames the compensator sends to a drive with the gms-comp firmware.

    Parameters
    ----------
    cfg
        The ``[can]`` section.
    """

    def __init__(self, cfg: CanConfig) -> None:
        self.cfg = cfg
        self.codec = E2eCodec()
        self.target_ids = frozenset({self.codec.command.frame_id})
        self.exclusive_ids = self.target_ids
        self.self_checked = True
        self.follows_sync = False
        self.sync: SyncCounter | None = None
        self.limit_raw = min(self.codec.limit_raw, self.codec.to_raw(cfg.max_current_A))
        self._last_status_data: bytes | None = None

    def to_raw(self, current_A: float) -> int:
        """Current in A -> the DBC's raw unit (0.1 mA)."""
        return self.codec.to_raw(current_A)

    def frames(self, cycle: int, raw: int) -> tuple[can.Message, list[can.Message]]:
        """FfCommand with the cycle as alive counter; nothing else."""
        return self.codec.command_frame(cycle, raw), []

    def traffic(self) -> list[tuple[int, float]]:
        """FfCommand every cycle, DriveStatus every ``status_every_cycles``."""
        rate = 1.0 / self.cfg.cycle_period_s
        return [
            (self.codec.command.length, rate),
            (self.codec.status.length, rate / self.cfg.status_every_cycles),
        ]

    def on_reply(self, msg: can.Message) -> None:
        """Keep the latest status frame (raw: decoded only when asked, off the loop's time)."""
        if msg.arbitration_id == self.codec.status.frame_id:
            self._last_status_data = bytes(msg.data)

    @property
    def last_status(self) -> DriveStatus | None:
        """The drive's latest intact status frame."""
        data = self._last_status_data
        return None if data is None else self.codec.check_status(data)

    def stop_frames(self) -> tuple[list[can.Message], str]:
        """Nothing: the firmware holds, then ramps to zero and waits for the next stream."""
        return [], "the firmware falls back to 0 A after rx_timeout and waits (state resync)"

    def report(self) -> dict[str, Any]:
        """No SYNC in this profile."""
        return {"sync_source": None}
