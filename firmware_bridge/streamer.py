"""The compensator side: one feedforward frame per control cycle, sent by the loop itself.

There is no background sender: if the loop stalls, the bus falls silent and the
drive's timeout fires. The :class:`Shaper` saturates the current before it is
encoded and ramps it to zero on stop or on a source fault. Each cycle first reads
what the drive published (its cycle, the session it holds), then sends: a command
while the drive holds this compensator's session, a request for it otherwise
(:mod:`firmware_bridge.freshness`). A frame of another node with this compensator's
identifiers, or the drive held by another session, ends the stream (:attr:`Streamer.taken`).
"""

from __future__ import annotations

import bisect
import math
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import can

from firmware_bridge.busload import bus_load
from firmware_bridge.freshness import (
    AGE_TOLERANCE_CYCLES,
    MAX_IN_DRIVE_LEVEL_RAW,
    PER_MILLE,
    Mode,
    age_by_time,
    is_fresh,
)
from firmware_bridge.profiles.base import CompensatorTx, get_profile
from firmware_bridge.settings import CanConfig
from firmware_bridge.supervisor import saturate, toward_zero
from gms_comp.errors import BusError


def make_tx(cfg: CanConfig) -> CompensatorTx:
    """The sending side of the configured profile."""
    return get_profile(cfg.profile).make_tx(cfg)


def profile_bus_load(cfg: CanConfig, tx: CompensatorTx) -> float:
    """Worst-case load of the profile's traffic plus the configured background."""
    return bus_load(tx.traffic(), cfg.bitrate_bit_s) + cfg.background_load


@dataclass
class Shaper:
    """Saturation and ramp-to-zero of the commanded value, in raw CAN units."""

    limit_raw: int
    ramp_cycles: int
    value_raw: int = 0

    def step(self, raw: int | None, limit_raw: int | None = None) -> int:
        """Next command; ``None`` asks for the ramp towards zero (stop or fault); a value is
        saturated at ``limit_raw`` (default: the current's limit)."""
        if raw is None:
            step = math.ceil(self.limit_raw / self.ramp_cycles)
            self.value_raw = toward_zero(self.value_raw, step)
        else:
            self.value_raw = saturate(raw, self.limit_raw if limit_raw is None else limit_raw)
        return self.value_raw


class Sender(Protocol):
    """What the streamer needs of a bus."""

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Send one frame."""
        ...

    def recv(self, timeout: float | None = None) -> can.Message | None:
        """The next frame, or None after ``timeout`` s."""
        ...


@dataclass
class Streamer:
    """Encodes and sends the feedforward of one control cycle."""

    cfg: CanConfig
    bus: Sender
    tx: CompensatorTx
    frames_sent: int = 0
    requests_sent: int = 0
    undated_cycles: int = 0  # cycles without the drive's clock: nothing sent
    inputs_missing: int = 0  # cycles whose motion input did not arrive: nothing sent
    send_errors: int = 0
    source_faults: int = 0
    foreign_frames: int = 0  # frames with our exclusive ids sent by another node
    taken: str | None = None  # why the channel is not this compensator's, once it is not
    in_drive: bool = False  # the drive runs its own observer: the source gives its level
    sent_log: list[tuple[float, float, bytes]] = field(default_factory=list)
    send_clock: Callable[[], float] | None = None  # stamps the log at the send, if given
    # What this node sent lately: some transports (udp_multicast) hand a node its own
    # frames back, which are echoes, not another node's.
    own_recent: deque[tuple[int, bytes]] = field(default_factory=lambda: deque(maxlen=256))

    def __post_init__(self) -> None:
        self.shaper = Shaper(self.tx.limit_raw, self.cfg.ramp_cycles)

    def _send(self, msg: can.Message) -> None:
        self.bus.send(msg)
        self.own_recent.append((msg.arbitration_id, bytes(msg.data)))

    def cycle(self, cycle: int, current_A: float | None, now_s: float, hold: bool = False) -> int:
        """Send cycle ``cycle``'s frames; ``None`` ramps towards zero, ``hold`` sends no
        feedforward frame (its input is missing: the drive holds, then times out).
        Returns the raw command.

        ``now_s`` is this side's clock (the drive's cycle is counted on from it).
        """
        self.drain_replies(now_s)
        if hold:
            self.inputs_missing += 1
            self._send_frames(None, Mode.COMMAND, self.tx.extra(cycle), now_s)
            return self.shaper.value_raw
        if current_A is not None and not math.isfinite(current_A):
            self.source_faults += 1
            current_A = None
        if self.tx.claim.granted and self.in_drive:  # the level, per mille
            mode = Mode.IN_DRIVE
            level = None if current_A is None else round(PER_MILLE * current_A)
            raw = self.shaper.step(level, MAX_IN_DRIVE_LEVEL_RAW)
        elif self.tx.claim.granted:
            mode = Mode.COMMAND
            raw = self.shaper.step(None if current_A is None else self.tx.to_raw(current_A))
        else:  # the drive applies nothing of ours until it grants the session
            mode, raw, self.shaper.value_raw = Mode.REQUEST, 0, 0
        frame = self.tx.feedforward(mode, raw, now_s)
        self.undated_cycles += frame is None
        self._send_frames(frame, mode, self.tx.extra(cycle), now_s)
        return raw

    def release(self, cycle: int, now_s: float) -> None:
        """End the session: a release frame (and the cycle's SYNC as master)."""
        self.drain_replies(now_s)
        if self.tx.claim.granted:
            frame = self.tx.feedforward(Mode.RELEASE, 0, now_s)
            self._send_frames(frame, Mode.RELEASE, self.tx.extra(cycle), now_s)

    def _send_frames(
        self,
        feedforward: can.Message | None,
        mode: Mode,
        extra: list[can.Message],
        now_s: float,
    ) -> None:
        # stamped on both sides of the send: the frame entered the bus in between,
        # however long the thread waited (GIL, scheduler) around the call
        before = now_s if self.send_clock is None else self.send_clock()
        try:
            if feedforward is not None:
                self._send(feedforward)
                self._log_sent(feedforward, mode, before, now_s)
            for msg in extra:
                self._send(msg)
        except can.CanError:
            self.send_errors += 1  # the bus is off; the drive's timeout takes over

    def _log_sent(self, msg: can.Message, mode: Mode, before: float, now_s: float) -> None:
        if mode in (Mode.COMMAND, Mode.IN_DRIVE):  # the audit's record of what may be applied
            self.frames_sent += 1
            after = now_s if self.send_clock is None else self.send_clock()
            self.sent_log.append((before, after, bytes(msg.data)))
        elif mode is Mode.REQUEST:
            self.requests_sent += 1

    def drain_replies(self, now_s: float = 0.0) -> None:
        """Hand every frame waiting on the bus to the profile; note another node's."""
        while (msg := self.bus.recv(timeout=0.0)) is not None:
            self.take_reply(msg, now_s)

    def take_reply(self, msg: can.Message, now_s: float) -> None:
        """One frame from the bus, handled at ``now_s``."""
        key = (msg.arbitration_id, bytes(msg.data))
        if key in self.own_recent:
            self.own_recent.remove(key)  # our own frame handed back by the transport
            return
        if msg.arbitration_id in self.tx.exclusive_ids:
            self.foreign_frames += 1
            self.taken = self.taken or (
                f"another node sends frame 0x{msg.arbitration_id:03X} on "
                f"{self.cfg.interface} channel {self.cfg.channel!r}"
            )
        self.tx.on_reply(msg, now_s)
        other = self.tx.claim.held_by_other
        if other:
            self.taken = self.taken or (
                f"drive node {self.cfg.drive_node_id} takes commands from another "
                f"compensator (session {other})"
            )


def check_channel_free(
    streamer: Streamer, listen_s: float, clock: Callable[[], float] = time.monotonic
) -> None:
    """Refuse to stream if another node sends our frames or holds the drive.

    One compensator per drive: listens ``listen_s`` for frames with the ids only
    this compensator may send (the feedforward frame; cia402 also its heartbeat and,
    as SYNC master, SYNC) and for the drive announcing a session of another
    compensator, and raises :class:`BusError` on the first.

    Parameters
    ----------
    streamer
        The compensator's streamer, before it sends anything.
    listen_s
        How long to listen; several cycles of the other node's stream.
    clock
        The clock the drive's status frames are handled on.
    """
    deadline = time.monotonic() + listen_s
    while (remaining := deadline - time.monotonic()) > 0:
        msg = streamer.bus.recv(timeout=remaining)
        if msg is not None:
            streamer.take_reply(msg, clock())
        if streamer.taken is not None:
            raise ChannelTakenError(streamer.taken)


class ChannelTakenError(BusError):
    """Another compensator streams to the same drive: one compensator per drive."""

    def __init__(self, reason: str) -> None:
        super().__init__(f"{reason}: one compensator per drive, stop the other one first")


def count_unsent_applied(
    sent: Sequence[tuple[float, float, bytes]],
    applied: Sequence[tuple[float, bytes]],
    period_s: float,
    max_age_cycles: int,
    transport_cycles: int = 0,
) -> int:
    """Applied frames that are not a payload the streamer sent within the validity window.

    An independent check of the receiver: whatever it applied must be exactly
    what was sent (corrupted payloads fail) and fresh by the one rule of
    :func:`~firmware_bridge.freshness.is_fresh` (stale or replayed frames fail).

    Parameters
    ----------
    sent
        ``(not_before_s, not_after_s, payload)`` per feedforward frame: the send call's bounds.
    applied
        ``(time_s, payload)`` per frame the drive applied, at the drive cycle it did.
    period_s
        The control cycle.
    max_age_cycles
        The validity window in cycles (``[can] max_frame_age_cycles``).
    transport_cycles
        Cycles a fresh frame takes from the send to its application
        (:func:`~firmware_bridge.freshness.transport_cycles`): 0 stepped, 1 in
        real time, plus one when the RPDO waits for the next SYNC. The drive
        judges by the same rule from the frame's reception stamp.

    Returns
    -------
    int
        The number of applied frames that fail the check.
    """
    sends: dict[bytes, tuple[list[float], list[float]]] = {}
    for before, after, data in sent:
        starts, ends = sends.setdefault(data, ([], []))
        starts.append(before)
        ends.append(after)
    bad = 0
    for t, data in applied:
        starts, ends = sends.get(data, ([], []))
        i = bisect.bisect_right(starts, t + AGE_TOLERANCE_CYCLES * period_s)  # begun by then
        if i == 0:
            bad += 1
            continue
        bad += not is_fresh(age_by_time(t, ends[i - 1], period_s, transport_cycles), max_age_cycles)
    return bad
