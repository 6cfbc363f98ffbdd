"""What a drive does with the feedforward values it receives, profile-independent.

Values are integers in the profile's CAN unit (per mille, 0.1 mA, ...), as a
drive firmware holds them. Each drive cycle the :class:`Supervisor` takes the
value that arrived fresh this cycle, if any: it applies it (saturated), holds
the last one while the link may just have hiccupped, and once the link counts as
lost ramps the output to zero at a rate that reaches zero from full scale within
the configured ramp time. ``firmware_bridge/c/ff_handler.c`` implements the same
rules for the firmware.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field


class Verdict(enum.Enum):
    """What the receiver did with one frame."""

    ACCEPTED = "accepted"  # a command of the held session, applied
    GRANTED = "granted"  # a request: the session is (or already was) the sender's
    RELEASED = "released"  # the held session's end, asked by its compensator
    CORRUPT = "corrupt"  # damaged, wrong length or out of the signal's range
    DUPLICATE = "duplicate"  # the same stamp as the last command taken
    OUT_OF_ORDER = "out_of_order"  # older than the last command taken
    STALE = "stale"  # older than the validity window by the drive's cycle
    EARLY = "early"  # dated in the drive's future
    FOREIGN = "foreign"  # of another session than the one held (or none granted)


REJECTIONS = (
    Verdict.CORRUPT,
    Verdict.DUPLICATE,
    Verdict.OUT_OF_ORDER,
    Verdict.STALE,
    Verdict.EARLY,
    Verdict.FOREIGN,
)


def saturate(value: int, limit: int) -> int:
    """``value`` clamped to ``[-limit, limit]``."""
    return max(-limit, min(limit, value))


def toward_zero(value: int, step: int) -> int:
    """``value`` moved by at most ``step`` towards zero, never past it."""
    return max(0, value - step) if value > 0 else min(0, value + step)


@dataclass
class Supervisor:
    """Hold, timeout and ramp-to-zero of the applied feedforward.

    Parameters
    ----------
    limit_raw
        Largest magnitude the drive applies.
    timeout_cycles
        Cycles without a fresh value after which the link counts as lost.
    ramp_cycles
        Cycles a full-scale ramp to zero may take.
    """

    limit_raw: int
    timeout_cycles: int
    ramp_cycles: int
    output_raw: int = 0
    cycles_since_fresh: int = field(default=0)
    link_lost: bool = True

    @property
    def ramp_step_raw(self) -> int:
        """Largest change per cycle of the ramp to zero."""
        return math.ceil(self.limit_raw / self.ramp_cycles)

    def end(self) -> None:
        """The link ends now (the session was released): ramp to zero from the next cycle."""
        self.link_lost = True

    def tick(self, fresh_raw: int | None, limit_raw: int | None = None) -> int:
        """Advance one drive cycle and return the value applied in it; a fresh value is
        saturated at ``limit_raw`` (default: the current's limit)."""
        if fresh_raw is not None:
            self.cycles_since_fresh = 0
            self.link_lost = False
            self.output_raw = saturate(
                fresh_raw, self.limit_raw if limit_raw is None else limit_raw
            )
            return self.output_raw
        self.cycles_since_fresh += 1
        if self.cycles_since_fresh > self.timeout_cycles:
            self.link_lost = True
        if self.link_lost:
            self.output_raw = toward_zero(self.output_raw, self.ramp_step_raw)
        return self.output_raw


@dataclass
class RejectCounts:
    """Frames seen by a receiver, by verdict."""

    counts: dict[Verdict, int] = field(default_factory=lambda: dict.fromkeys(Verdict, 0))

    def add(self, verdict: Verdict) -> None:
        """Count one frame with ``verdict``."""
        self.counts[verdict] += 1

    @property
    def rejected(self) -> dict[str, int]:
        """Rejected frames by reason."""
        return {v.value: self.counts[v] for v in REJECTIONS}

    @property
    def total_rejected(self) -> int:
        """All rejected frames."""
        return sum(self.counts[v] for v in REJECTIONS)
