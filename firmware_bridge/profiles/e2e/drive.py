"""The emulated drive of e2e: the receiver, plus the status frame the firmware sends back."""

from __future__ import annotations

import can

from firmware_bridge.profiles.e2e.codec import E2eCodec
from firmware_bridge.profiles.e2e.receiver import E2eReceiver
from firmware_bridge.settings import CanConfig
from firmware_bridge.supervisor import RejectCounts, Supervisor, Verdict

STATE_NAMES = ("waiting", "active", "hold", "fallback")  # the DBC's DriveStatus.State


class E2eDrive:
    """The drive side of e2e on ``bus`` (implements ``DriveSide``).

    Parameters
    ----------
    cfg
        The ``[can]`` section.
    bus
        The drive's bus handle, for its status frames.
    """

    def __init__(self, cfg: CanConfig, bus: can.BusABC) -> None:
        self.cfg = cfg
        self.bus = bus
        codec = E2eCodec()
        limit = min(codec.limit_raw, codec.to_raw(cfg.max_current_A))
        supervisor = Supervisor(limit, cfg.timeout_cycles, cfg.ramp_cycles)
        self.receiver = E2eReceiver(codec, supervisor, cfg.max_frame_age_cycles)

    @property
    def counts(self) -> RejectCounts:
        """Received frames by verdict."""
        return self.receiver.counts

    def handle(self, msg: can.Message, now_s: float) -> None:
        """Check FfCommand frames; an error frame counts as a corrupt one."""
        if msg.arbitration_id == self.receiver.codec.command.frame_id:
            self.receiver.on_frame(bytes(msg.data))
        elif msg.is_error_frame:
            self.receiver.counts.add(Verdict.CORRUPT)

    def set_real_time(self, real_time: bool) -> None:
        """Nothing to set: the drive's cycle dates every frame, stepped or in real time."""

    def tick(self, now_s: float, cycle: int) -> tuple[int, bytes | None]:
        """One drive cycle; then the status frame (every ``status_every_cycles``)."""
        receiver = self.receiver
        fresh = receiver.fresh_data
        receiver.fresh_data = None
        out = receiver.tick()
        if receiver.last_cycle % self.cfg.status_every_cycles == 0:
            self.bus.send(
                receiver.codec.status_frame(
                    receiver.last_cycle,
                    out,
                    receiver.clock.session,
                    receiver.state,
                    self.counts.total_rejected,
                )
            )
        return out, fresh

    def from_raw(self, raw: int) -> float:
        """0.1 mA -> A."""
        return self.receiver.codec.from_raw(raw)

    def state(self) -> str:
        """The receiver's DriveStatus.State, by name."""
        return STATE_NAMES[self.receiver.state]

    def emcy(self) -> list[str]:
        """The firmware sends no EMCY."""
        return []
