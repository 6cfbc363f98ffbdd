"""The drive side of e2e: check CRC and ranges, date by the drive's cycle, apply, supervise.

``firmware_bridge/c/ff_handler.c`` implements the same rules for the firmware.
"""

from __future__ import annotations

from firmware_bridge.freshness import DriveClock, Mode, session_timeout_cycles
from firmware_bridge.profiles.e2e.codec import E2eCodec
from firmware_bridge.supervisor import RejectCounts, Supervisor, Verdict


class E2eReceiver:
    """The drive's side of the e2e profile: check, classify, apply, supervise.

    A command is applied only if its CRC holds, its fields are in the DBC's ranges,
    it belongs to the session the drive holds and it is fresh by the drive's cycle
    (:mod:`firmware_bridge.freshness`, the one definition). Frames are judged on
    arrival against the cycle of the next :meth:`tick`, which applies the newest
    command accepted since the last one and then moves to the next cycle.
    """

    WAITING, ACTIVE, HOLD, FALLBACK = range(4)  # the DBC's DriveStatus.State values

    def __init__(self, codec: E2eCodec, supervisor: Supervisor, max_age_cycles: int) -> None:
        self.codec = codec
        self.supervisor = supervisor
        self.clock = DriveClock(max_age_cycles, session_timeout_cycles(supervisor.timeout_cycles))
        self.counts = RejectCounts()
        self.fresh_raw: int | None = None
        self.fresh_data: bytes | None = None
        self.fresh_in_drive = False
        self.in_drive = False  # the value applied is the level of the drive's own observer
        self.last_cycle = 0  # the cycle the last tick ran

    def on_frame(self, data: bytes) -> Verdict:
        """Check one FfCommand payload; count and return the verdict."""
        verdict = self._classify(data)
        self.counts.add(verdict)
        return verdict

    def _classify(self, data: bytes) -> Verdict:
        command = self.codec.check_command(data)
        if command is None:
            return Verdict.CORRUPT
        verdict = self.clock.judge(command.cycle, command.session, command.mode)
        if verdict is Verdict.ACCEPTED:
            self.fresh_raw, self.fresh_data = command.raw, bytes(data)
            self.fresh_in_drive = command.mode is Mode.IN_DRIVE
        elif verdict is Verdict.RELEASED:
            self.fresh_raw = self.fresh_data = None
            self.supervisor.end()
        return verdict

    def tick(self) -> int:
        """One drive cycle: apply the fresh value, if any; the applied raw value."""
        if self.fresh_raw is not None:
            self.in_drive = self.fresh_in_drive
        out = self.supervisor.tick(self.fresh_raw)
        self.fresh_raw = None
        self.last_cycle = self.clock.cycle
        self.clock.advance()
        return out

    @property
    def state(self) -> int:
        """The DBC's DriveStatus.State value of the receiver now."""
        if self.supervisor.link_lost:
            return self.FALLBACK if self.supervisor.output_raw else self.WAITING
        return self.ACTIVE if self.supervisor.cycles_since_fresh == 0 else self.HOLD
