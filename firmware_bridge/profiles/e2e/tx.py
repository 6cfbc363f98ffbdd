"""The compensator side of e2e: one FfCommand per cycle; the drive's status frame back."""

from __future__ import annotations

from typing import Any

import can

from firmware_bridge.freshness import DriveTime, Mode
from firmware_bridge.profiles.base import Claim, SyncCounter
from firmware_bridge.profiles.e2e.codec import DriveStatus, E2eCodec
from firmware_bridge.settings import CanConfig


class E2eTx:
    """Frames the compensator sends to a drive with the gms-comp firmware.

    Parameters
    ----------
    cfg
        The ``[can]`` section.

    The drive's clock comes from its status frames: a frame sent now is stamped with
    the last cycle the drive published plus the whole periods passed since this side
    handled it (by its own clock), plus one; at most ``status_every_cycles +
    timeout_cycles`` periods are counted.
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
        horizon = cfg.status_every_cycles + cfg.timeout_cycles
        self.claim = Claim(DriveTime(cfg.cycle_period_s, horizon))
        self._last_status_data: bytes | None = None

    def to_raw(self, current_A: float) -> int:
        """Current in A -> the DBC's raw unit (0.1 mA)."""
        return self.codec.to_raw(current_A)

    def feedforward(self, mode: Mode, raw: int, now_s: float) -> can.Message | None:
        """FfCommand stamped with the drive cycle it applies at; None without the drive's clock."""
        stamp = self.claim.time.stamp(now_s)
        if stamp is None:
            return None
        return self.codec.command_frame(stamp, raw, self.claim.session, mode)

    def extra(self, cycle: int) -> list[can.Message]:
        """Nothing besides FfCommand."""
        return []

    def traffic(self) -> list[tuple[int, float]]:
        """FfCommand every cycle, DriveStatus every ``status_every_cycles``."""
        rate = 1.0 / self.cfg.cycle_period_s
        return [
            (self.codec.command.length, rate),
            (self.codec.status.length, rate / self.cfg.status_every_cycles),
        ]

    def on_reply(self, msg: can.Message, now_s: float) -> None:
        """An intact status frame gives the drive's cycle and session."""
        if msg.arbitration_id == self.codec.status.frame_id:
            status = self.codec.check_status(bytes(msg.data))
            if status is not None:
                self._last_status_data = bytes(msg.data)
                self.claim.time.observe(status.cycle, status.session, now_s)

    @property
    def last_status(self) -> DriveStatus | None:
        """The drive's latest intact status frame."""
        data = self._last_status_data
        return None if data is None else self.codec.check_status(data)

    def stop_frames(self) -> tuple[list[can.Message], str]:
        """Nothing beyond the release: the firmware ramps to zero and waits for a request."""
        return [], "session released: the firmware holds 0 A and waits for a new request"

    def report(self) -> dict[str, Any]:
        """No SYNC in this profile."""
        return {"sync_source": None}
