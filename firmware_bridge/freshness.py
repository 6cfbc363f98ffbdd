"""When a frame may be applied: the drive's cycle as the one clock, sessions as the one claim.

A frame is dated by the **drive's own cycle** (its count of control ticks, on its own
clock), which the drive publishes after a tick (e2e: ``DriveStatus.Cycle``; cia402:
object 0x2002 in its TPDO1, sent at the tick after a SYNC). The compensator never
invents a date: it stamps each feedforward frame with the earliest drive cycle at
which the frame can be applied: the last cycle the drive published, plus one, plus
the whole periods of its own clock since it handled that status (at most
``horizon_cycles``), plus one for a frame that waits for the next SYNC
(:class:`DriveTime`). Every term can only lag the truth: a published cycle is already
over when it arrives, and a delay of the status or of the feedforward frame itself
only makes the frame look *older* to the drive. So no delay,
however long or steady, can make a late frame look fresh, and there is nothing to
re-anchor (the receiver keeps no correspondence between its clock and the sender's).

The rule, shared by :class:`DriveClock` (both emulated drives),
``firmware_bridge/c/ff_handler.c`` (the firmware) and, by time, the stream audit
(:func:`firmware_bridge.streamer.count_unsent_applied`):

    a frame stamped ``s`` is fresh at drive cycle ``n`` if
    ``0 <= n - s <= max_age_cycles`` (modulo 2**16; boundary **included**).

``n - s < 0`` is a frame dated in the drive's future: a sender whose clock runs fast,
refused as ``early``. A command must also be newer than the last one taken in its
session (else ``duplicate`` or ``out_of_order``).

**Sessions.** The drive holds at most one session: the 8-bit id of the compensator it
takes commands from, announced in every status frame (0: none). A compensator asks
for one with *request* frames (no current, a random id, stamped like any frame); the
drive grants the first fresh request while it holds none. Commands of any other
session are refused as ``foreign`` and never applied. The session ends with the
compensator's *release* frame (a clean stop: the output ramps to zero at once) or
after :data:`SESSION_TIMEOUT_FACTOR` times ``rx_timeout`` without a fresh frame of it
(a compensator gone without a word; the link itself is lost, and the output ramping,
after one ``rx_timeout``). A restarted or second compensator (another random id) comes
in only through an explicit request once the session is free, never because its
frames keep coming; a delayed link keeps its session but gets nothing applied.

Wrap-around: stamps are 16-bit, so a frame held up for 65 536 cycles (65.5 s at
1 kHz) plus or minus the window would date like a fresh one; the link is lost, and
the session with it, after ``rx_timeout``, so such a frame would also need a request
of the same random session id granted just before it: documented, not guarded.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

from firmware_bridge.supervisor import Verdict

STAMP_MODULUS = 1 << 16
"""Stamps and drive cycles count modulo this (16 bits on the wire)."""
SESSION_IDS = range(1, 256)
"""Session ids a compensator may draw; 0 means "no session"."""
PER_MILLE = 1000
MAX_IN_DRIVE_LEVEL_RAW = 4000
"""An in-drive observer's level (per mille) at most four times its table's friction."""
SESSION_TIMEOUT_FACTOR = 10
"""A session ends after this many link timeouts without a fresh frame of it."""
AGE_TOLERANCE_CYCLES = 1e-6
"""Slack on the boundary for ages computed from float times, in cycles (1 ns at 1 ms)."""


class Mode(enum.IntEnum):
    """What a feedforward frame asks of the drive (the frames' ``Mode`` field)."""

    COMMAND = 0  # apply this current (in the held session)
    REQUEST = 1  # grant me the session (no current)
    RELEASE = 2  # my stream ends here: release the session, ramp to zero
    IN_DRIVE = 3  # run your own observer, at this friction level (per mille)


@dataclass(frozen=True)
class Command:
    """The dating and claim fields of an intact feedforward frame, with its raw current."""

    cycle: int  # the stamp: the drive cycle the frame is applied at
    raw: int  # the current in the profile's raw unit
    session: int
    mode: Mode


def session_timeout_cycles(timeout_cycles: int) -> int:
    """Cycles a session outlives its last fresh frame: :data:`SESSION_TIMEOUT_FACTOR`
    link timeouts (``[can] rx_timeout_s`` in cycles)."""
    return SESSION_TIMEOUT_FACTOR * timeout_cycles


def is_fresh(age_cycles: float, max_age_cycles: float) -> bool:
    """Whether a frame ``age_cycles`` old may be applied; the boundary is included.

    Parameters
    ----------
    age_cycles
        Age of the frame in drive cycles (an integer on the drive, a float in the
        audit, where it comes from timestamps).
    max_age_cycles
        The validity window in cycles.

    Returns
    -------
    bool
        ``age_cycles <= max_age_cycles`` up to :data:`AGE_TOLERANCE_CYCLES`.
    """
    return age_cycles <= max_age_cycles + AGE_TOLERANCE_CYCLES


def stamp_age(cycle: int, stamp: int) -> int:
    """``cycle - stamp`` modulo :data:`STAMP_MODULUS`, as a signed number of cycles."""
    diff = (cycle - stamp) % STAMP_MODULUS
    return diff - STAMP_MODULUS if diff >= STAMP_MODULUS // 2 else diff


def transport_cycles(real_time: bool, waits_for_sync: bool) -> int:
    """Cycles a fresh frame takes from its send to its application, for the audit.

    Parameters
    ----------
    real_time
        The drive runs on its own clock and applies a frame at its next cycle
        after the arrival (stepped, it applies in the cycle of the arrival).
    waits_for_sync
        The frame waits for the next SYNC after it (a SYNC follower's RPDO,
        sent in answer to one SYNC and applied at the next).

    Returns
    -------
    int
        0 stepped, 1 in real time, one more when the frame waits for the next SYNC.
    """
    return int(real_time) + int(waits_for_sync)


def age_by_time(apply_s: float, sent_s: float, period_s: float, transport: int) -> float:
    """Age in cycles, by the audit's clock, of a frame sent at ``sent_s``, applied at ``apply_s``.

    Parameters
    ----------
    apply_s
        Start of the drive cycle that applies the frame, in s.
    sent_s
        When the frame left the sender (the end of the send call), in s, same clock.
    period_s
        The control cycle, in s.
    transport
        :func:`transport_cycles` of the stream.

    Returns
    -------
    float
        ``(apply_s - sent_s) / period_s - transport``, compared with :func:`is_fresh`.
    """
    return (apply_s - sent_s) / period_s - transport


@dataclass
class DriveClock:
    """The drive side: its cycle, the session it holds, and the verdict on each frame.

    Parameters
    ----------
    max_age_cycles
        Validity window: the largest age, in drive cycles, of a frame taken.
    session_timeout_cycles
        A session without a granted request or an accepted command for longer ends
        (:func:`session_timeout_cycles` of the link's timeout).

    ``cycle`` is the drive cycle a frame judged now is applied at. Call
    :meth:`advance` once per drive cycle (it also ends an idle session) and
    :meth:`judge` for each intact frame.
    """

    max_age_cycles: int
    session_timeout_cycles: int = 30
    cycle: int = 0
    session: int = 0
    last_stamp: int | None = None  # newest stamp taken in the held session
    idle_cycles: int = 0  # cycles since the held session's last granted or accepted frame

    def advance(self) -> None:
        """The next drive cycle begins; a session idle for too long ends."""
        self.cycle = (self.cycle + 1) % STAMP_MODULUS
        self.idle_cycles += 1
        if self.session and self.idle_cycles > self.session_timeout_cycles:
            self.release()

    def release(self) -> None:
        """End the held session (link lost, or released): a new request is needed."""
        self.session = 0
        self.last_stamp = None

    def judge(self, stamp: int, session: int, mode: Mode) -> Verdict:
        """Verdict on an intact frame; a granted request or an accepted command is taken.

        Parameters
        ----------
        stamp
            The drive cycle the frame was made for.
        session
            The sender's session id.
        mode
            What the frame asks (:class:`Mode`).
        """
        age = stamp_age(self.cycle, stamp)
        if age < 0:
            return Verdict.EARLY
        if not is_fresh(age, self.max_age_cycles):
            return Verdict.STALE
        if session == 0 or (self.session not in (0, session)):
            return Verdict.FOREIGN
        if mode is Mode.REQUEST:
            if self.session == 0:
                self.session, self.last_stamp = session, None
            self.idle_cycles = 0
            return Verdict.GRANTED
        if self.session == 0:
            return Verdict.FOREIGN  # a command (or release) of a session not granted
        if self.last_stamp is not None:
            newer = stamp_age(stamp, self.last_stamp)
            if newer == 0:
                return Verdict.DUPLICATE
            if newer < 0:
                return Verdict.OUT_OF_ORDER
        if mode is Mode.RELEASE:
            self.release()
            return Verdict.RELEASED
        self.last_stamp = stamp  # a command, or the in-drive observer's level
        self.idle_cycles = 0
        return Verdict.ACCEPTED


@dataclass
class DriveTime:
    """The compensator side: the drive cycle a frame sent now applies at, at the earliest.

    Parameters
    ----------
    period_s
        The drive cycle, to count the cycles passed since the drive's last status by
        this side's clock.
    horizon_cycles
        Counting further than this from the last status is guessing: no date then.
    lead_cycles
        Cycles the frame waits on top of the transport the audit grants every frame (a
        SYNC follower's RPDO waits for the next SYNC: 1).

    The drive publishes the tick it has just run; the status is handled at ``seen_s``
    (no earlier than that tick) and a frame sent at ``now_s`` reaches the drive no
    earlier than ``now_s``: so the first tick after the send is at least the published
    one plus one plus the whole periods from ``seen_s`` to ``now_s``. That is the stamp,
    plus the lead. Whatever the delays, the drive then dates every frame at least as
    old as the stream audit does by the wall clock (``tests/test_can_freshness.py``).
    """

    period_s: float
    horizon_cycles: int
    lead_cycles: int = 0
    cycle: int | None = None  # the last cycle the drive published
    session: int = 0  # the session it announced with it
    seen_s: float = 0.0  # when that status was handled, by this side's clock

    def observe(self, cycle: int, session: int, now_s: float) -> None:
        """The drive published ``cycle`` (just run) and its ``session``; handled at ``now_s``."""
        self.cycle, self.session, self.seen_s = cycle, session, now_s

    def stamp(self, now_s: float) -> int | None:
        """The stamp of a frame sent at ``now_s``: the drive cycle it applies at, or None.

        None before the drive has published its cycle, or when the last status is more
        than ``horizon_cycles`` old: the frame is then not sent (the drive's timeout
        takes over), never dated by a guess.
        """
        if self.cycle is None:
            return None
        passed = max(0, math.floor((now_s - self.seen_s) / self.period_s))
        if passed > self.horizon_cycles:
            return None
        return (self.cycle + passed + 1 + self.lead_cycles) % STAMP_MODULUS
