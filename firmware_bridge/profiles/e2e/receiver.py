"""The drive side of e2e: check CRC and range, date by the alive counter, apply, supervise.

``firmware_bridge/c/ff_handler.c`` implements the same rules for the firmware.
"""

from __future__ import annotations

from firmware_bridge.freshness import (
    FrameClock,
    refuse_outlived,
    slot_margin_cycles,
    transport_cycles,
)
from firmware_bridge.profiles.e2e.codec import E2eCodec
from firmware_bridge.supervisor import RejectCounts, Supervisor, Verdict


class E2eReceiver:
    """The drive's side of the e2e profile: check, classify, apply, supervise.

    A frame is applied only if its CRC holds, its value is in the DBC's range,
    its counter is newer than the last accepted one and its age is within
    ``max_age_cycles`` (see :mod:`firmware_bridge.freshness`, the one
    definition of a stale frame). The first intact frame ever only sets the
    counter reference. Given the times (:meth:`on_frame`'s ``received_s``,
    :meth:`tick`'s ``now_s``), an accepted frame is dated once more by time (its
    slot, :meth:`FrameClock.sent_by`) when it would be applied (``period_s`` the drive cycle).
    """

    RESYNC, ACTIVE, HOLD, FALLBACK = range(4)  # the DBC's DriveStatus.State values

    def __init__(
        self,
        codec: E2eCodec,
        supervisor: Supervisor,
        max_age_cycles: int,
        period_s: float | None = None,
    ) -> None:
        self.codec = codec
        self.supervisor = supervisor
        self.clock = FrameClock(max_age_cycles, period_s)
        self.counts = RejectCounts()
        self.fresh_raw: int | None = None
        self.fresh_data: bytes | None = None
        self.fresh_sent_s: float | None = None

    def set_real_time(self, real_time: bool) -> None:
        """Whether the drive runs on its own clock (it applies at its next cycle)."""
        self.clock.transport_cycles = transport_cycles(real_time, waits_for_sync=False)
        self.clock.slot_margin_cycles = slot_margin_cycles(real_time)

    def on_frame(self, data: bytes, received_s: float | None = None) -> Verdict:
        """Check one FfCommand payload received at ``received_s``; count and return the verdict."""
        verdict = self._classify(data, received_s)
        self.counts.add(verdict)
        return verdict

    def _classify(self, data: bytes, received_s: float | None) -> Verdict:
        checked = self.codec.check_command(data)
        if checked is None:
            return Verdict.CORRUPT
        counter, raw = checked
        verdict = self.clock.judge(counter, received_s)
        if verdict is Verdict.ACCEPTED:
            self.fresh_raw = raw
            self.fresh_data = bytes(data)
            self.fresh_sent_s = (
                None if received_s is None else self.clock.sent_by(counter, received_s)
            )
        return verdict

    def tick(self, now_s: float | None = None) -> int:
        """One drive cycle (at ``now_s``): apply the fresh value, if any; the applied raw value."""
        sent_s = self.fresh_sent_s
        if (
            self.fresh_raw is not None
            and now_s is not None
            and sent_s is not None
            and self.clock.outlived(sent_s, now_s)
        ):
            refuse_outlived(self.counts)
            self.fresh_raw = self.fresh_data = None
        was_lost = self.supervisor.link_lost
        out = self.supervisor.tick(self.fresh_raw)
        self.fresh_raw = self.fresh_sent_s = None
        self.clock.tick()
        if self.supervisor.link_lost and not was_lost:
            self.clock.link_lost()
        return out

    @property
    def state(self) -> int:
        """The DBC's DriveStatus.State value of the receiver now."""
        if self.supervisor.link_lost:
            return self.FALLBACK if self.supervisor.output_raw else self.RESYNC
        return self.ACTIVE if self.supervisor.cycles_since_fresh == 0 else self.HOLD
