"""When a received frame counts as stale: the one definition of the drive side and the audit.

Every feedforward frame carries an 8-bit alive counter: the compensator's
control-cycle index modulo 256 (e2e: the DBC's ``Counter`` signal; cia402: the
object 0x2001 mapped into RPDO1 beside 0x60B2). The drive dates a frame by that
counter against its own cycle count: the first frame ever sets the
correspondence (the *anchor*), and a frame's **age** is how many drive cycles
it arrives after the cycle its counter belongs to.

The rule, shared by :class:`FrameClock`, ``firmware_bridge/c/ff_handler.c``
and the stream audit (:func:`firmware_bridge.streamer.count_unsent_applied`):

    a frame is fresh if ``age <= max_age_cycles`` (boundary **included**),
    compared through :func:`is_fresh` with a tolerance of
    :data:`AGE_TOLERANCE_CYCLES` for ages measured in float time.

Besides, a frame must be newer than the last one applied (else it is a
duplicate or out of order) while that one is itself fresh. A frame that
arrives early (negative age) shows the anchor was set by a late
frame: the anchor moves to it, so ages only ever get stricter. The anchor
outlives a lost link (compensator and drive keep counting cycles), so the first
frame after an outage is judged like any other. Only a steady run of
:data:`REANCHOR_FRAMES` consecutive frames that are all late by the same amount
(a restarted compensator, a drifted clock) re-anchors, without applying them.

The counter dates a frame by the cycle it was made for, in whole drive cycles;
it cannot see a frame held up in the sender after its cycle began (a
compensator descheduled between sending the RPDO and the SYNC that applies it),
nor where in a drive cycle the compensator's cycle began (a frame held up for
3.008 cycles still counts 3). So a receiver that runs on time also dates each
frame by time and, at the moment it would apply it, refuses a frame whose
:func:`age_by_time` exceeds the window: the audit's own rule and
:func:`transport_cycles`, with the send end replaced by the earliest time the
frame can have been sent, which comes no later: its **slot**, the reception
stamp (a controller's hardware receive timestamp; python-can's
``msg.timestamp``) of the earliest frame received so far (relative to its
counter), advanced one period per counter step (:meth:`FrameClock.sent_by`). A
frame must pass both rules. The slot moves only earlier (each frame received
before its slot moves it) and is set again with the anchor. A drive on its own
clock takes it :data:`SLOT_MARGIN_CYCLES` earlier still (:func:`slot_margin_cycles`):
a held-up frame may have left earlier in its cycle than any frame seen so far,
which neither its counter nor its reception shows. With the drive applying at
its next tick, this rule is the counter's less the phase of the slot in the
drive's cycle plus the margin: it refuses a frame of counter age equal to the
window exactly when the compensator's cycles begin within the margin after the
drive's ticks, where the counter cannot tell one cycle from the next.
"""

from __future__ import annotations

from dataclasses import dataclass

from firmware_bridge.supervisor import RejectCounts, Verdict

COUNTER_MODULUS = 256
AGE_TOLERANCE_CYCLES = 1e-6
"""Slack on the boundary for ages computed from float times, in cycles (1 ns at 1 ms)."""
MAX_EARLY_CYCLES = COUNTER_MODULUS // 4
"""A frame further ahead of the anchor than this is taken as an old one, wrapped around."""
_AGE_CAP = 2**30
REANCHOR_FRAMES = 16
"""Consecutive frames late by the same amount that re-establish the anchor."""
SLOT_MARGIN_CYCLES = 0.25
"""How much earlier in its cycle than any frame seen so far a real-time sender may send."""


def is_fresh(age_cycles: float, max_age_cycles: float) -> bool:
    """Whether a frame ``age_cycles`` old may be applied; the boundary is included.

    Parameters
    ----------
    age_cycles
        Age of the frame in control cycles (an integer on the drive, a float in
        the audit, where it comes from timestamps).
    max_age_cycles
        The validity window in cycles.

    Returns
    -------
    bool
        ``age_cycles <= max_age_cycles`` up to :data:`AGE_TOLERANCE_CYCLES`.
    """
    return age_cycles <= max_age_cycles + AGE_TOLERANCE_CYCLES


def transport_cycles(real_time: bool, waits_for_sync: bool) -> int:
    """Cycles a fresh frame takes from its send to its application, beyond its age.

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


def slot_margin_cycles(real_time: bool) -> float:
    """How much earlier than its slot a frame is taken to have left, in cycles.

    Parameters
    ----------
    real_time
        The drive runs on its own clock (stepped, both sides count one clock).

    Returns
    -------
    float
        :data:`SLOT_MARGIN_CYCLES` in real time, 0 stepped.
    """
    return SLOT_MARGIN_CYCLES if real_time else 0.0


def age_by_time(apply_s: float, sent_s: float, period_s: float, transport: int) -> float:
    """Age in cycles of a frame sent (or received) at ``sent_s`` and applied at ``apply_s``.

    Parameters
    ----------
    apply_s
        Start of the drive cycle that applies the frame, in s.
    sent_s
        When the frame left the sender (the audit: the end of the send call) or
        reached the receiver (the drive: its reception stamp), in s, on the same clock.
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


def refuse_outlived(counts: RejectCounts) -> None:
    """Count a frame accepted by its counter but refused by its reception stamp as stale."""
    counts.counts[Verdict.ACCEPTED] -= 1
    counts.add(Verdict.STALE)


def _signed(value: int) -> int:
    """``value`` modulo the counter range, as a signed difference."""
    value %= COUNTER_MODULUS
    return value - COUNTER_MODULUS if value >= COUNTER_MODULUS // 2 else value


@dataclass
class FrameClock:
    """Classifies frames by their alive counter against the receiver's cycle count.

    Parameters
    ----------
    max_age_cycles
        Validity window: the largest age, in drive cycles, of an applied frame.
    period_s
        The drive cycle in s, for :meth:`outlived`; None: no rule by reception stamp.
    transport_cycles
        :func:`transport_cycles` of the drive's mode (0: stepped, the default).
    slot_margin_cycles
        :func:`slot_margin_cycles` of the drive's mode (0: stepped, the default).

    Call :meth:`judge` for each intact frame, :meth:`tick` once per drive
    cycle, :meth:`link_lost` when the supervisor declares the link lost, and
    :meth:`outlived` on the frame about to be applied.
    """

    max_age_cycles: int
    period_s: float | None = None
    transport_cycles: int = 0
    slot_margin_cycles: float = 0.0
    cycle: int = 0  # drive cycles, modulo the counter range
    anchored: bool = False
    offset: int = 0  # drive cycle minus counter of a frame of age 0
    last_counter: int | None = None
    last_age: int = 0  # age of the last accepted frame, counted up without wrapping
    origin_s: float | None = None  # slot of counter step 0: earliest reception - steps x period
    _late_offset: int | None = None
    _late_run: int = 0
    _late_counter: int = 0

    def tick(self) -> None:
        """One drive cycle has passed."""
        self.cycle = (self.cycle + 1) % COUNTER_MODULUS
        self.last_age = min(self.last_age + 1, _AGE_CAP)

    def link_lost(self) -> None:
        """Forget the last counter (the anchor stays): any newer frame may follow."""
        self.last_counter = None

    def outlived(self, sent_s: float, apply_s: float) -> bool:
        """Whether a frame sent at ``sent_s`` at the earliest is too old to apply at ``apply_s``.

        The second rule, by time (see the module docstring): not :func:`is_fresh`
        by :func:`age_by_time`. ``sent_s`` is :meth:`sent_by` of the frame (or
        its reception stamp). Both times in s, on one clock.
        """
        if self.period_s is None:
            return False
        age = age_by_time(apply_s, sent_s, self.period_s, self.transport_cycles)
        return not is_fresh(age, self.max_age_cycles)

    def sent_by(self, counter: int, received_s: float) -> float:
        """The earliest time the frame with ``counter``, received at ``received_s``, was sent.

        Its slot (module docstring) less the margin, or its reception stamp if
        that is earlier (no slot yet, or no period). Call after :meth:`judge` of
        the frame with the same stamp, which has moved the slot to it if it came
        earlier.
        """
        if self.period_s is None or self.origin_s is None:
            return received_s
        slot = self._slot(counter, received_s)
        return min(received_s, slot - self.slot_margin_cycles * self.period_s)

    def _slot(self, counter: int, received_s: float) -> float:
        """Slot of the counter step nearest the reception (the counter unwrapped by time)."""
        assert self.period_s is not None and self.origin_s is not None
        steps = (received_s - self.origin_s) / self.period_s
        unwrapped = counter + COUNTER_MODULUS * round((steps - counter) / COUNTER_MODULUS)
        return self.origin_s + unwrapped * self.period_s

    def _set_origin(self, counter: int, received_s: float | None, earlier_only: bool) -> None:
        if received_s is None or self.period_s is None:
            return
        if self.origin_s is None or not earlier_only:
            self.origin_s = received_s - counter * self.period_s
        elif received_s < (slot := self._slot(counter, received_s)):
            self.origin_s -= slot - received_s

    def age(self, counter: int) -> int:
        """Drive cycles the frame with ``counter`` arrives after its own cycle."""
        return _signed(self.cycle - counter - self.offset)

    def judge(self, counter: int, received_s: float | None = None) -> Verdict:
        """Verdict on an intact frame carrying ``counter``; accepted frames are the new last.

        ``received_s``, the frame's reception stamp, moves the slot (:meth:`sent_by`)
        when the frame is accepted or anchors.
        """
        if not self.anchored:
            self._anchor(counter, received_s)
            return Verdict.RESYNC
        # order against the last accepted frame while it is itself fresh; once it is
        # older than the window, any frame older still is stale by its age anyway
        last = self.last_counter
        if last is not None and is_fresh(self.last_age, self.max_age_cycles):
            delta = (counter - last) % COUNTER_MODULUS
            if delta == 0:
                return Verdict.DUPLICATE
            if delta >= COUNTER_MODULUS // 2:
                return Verdict.OUT_OF_ORDER
        age = self.age(counter)
        if not is_fresh(age, self.max_age_cycles) or age < -MAX_EARLY_CYCLES:
            return self._late(counter, received_s)
        if age < 0:  # the anchor came from a late frame: this one is earlier
            self.offset = (self.offset + age) % COUNTER_MODULUS
        self._set_origin(counter, received_s, earlier_only=True)
        self._late_run = 0
        self.last_counter = counter
        self.last_age = max(age, 0)
        return Verdict.ACCEPTED

    def _late(self, counter: int, received_s: float | None) -> Verdict:
        offset = (self.cycle - counter) % COUNTER_MODULUS
        steady = (
            self._late_run > 0
            and offset == self._late_offset
            and (counter - self._late_counter) % COUNTER_MODULUS == 1
        )
        self._late_run = self._late_run + 1 if steady else 1
        self._late_offset, self._late_counter = offset, counter
        if self._late_run >= REANCHOR_FRAMES:
            self._anchor(counter, received_s)
            return Verdict.RESYNC
        return Verdict.STALE

    def _anchor(self, counter: int, received_s: float | None) -> None:
        self._set_origin(counter, received_s, earlier_only=False)
        self.anchored = True
        self.offset = (self.cycle - counter) % COUNTER_MODULUS
        self.last_counter = counter
        self.last_age = 0
        self._late_run = 0
