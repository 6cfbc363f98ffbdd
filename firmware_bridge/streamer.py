"""The compensator side: one feedforward frame per control cycle, sent by the loop itself.

There is no background sender: if the loop stalls, the bus falls silent and the
drive's timeout fires. The :class:`Shaper` saturates the current before it is
encoded and ramps it to zero on stop or on a source fault.
"""

from __future__ import annotations

import bisect
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import can

from gms_comp.errors import BusError

from .busload import bus_load
from .cia402 import Cia402Codec, load_drive_od
from .e2e import DriveStatus, E2eCodec
from .freshness import AGE_TOLERANCE_CYCLES, is_fresh
from .settings import CanConfig
from .supervisor import saturate, toward_zero

_BOOTUP = b"\x00"  # NMT boot-up: the same COB-ID as the heartbeat, not one


class CompensatorTx(Protocol):
    """What the streamer needs from a profile."""

    target_ids: frozenset[int]  # ids of the feedforward frames (what faults act on)
    exclusive_ids: frozenset[int]  # ids no other node may send while this one streams
    self_checked: bool  # feedforward frames carry their own CRC
    limit_raw: int

    def to_raw(self, current_A: float) -> int: ...

    def frames(self, cycle: int, raw: int) -> tuple[can.Message, list[can.Message]]: ...

    def traffic(self) -> list[tuple[int, float]]: ...

    def on_reply(self, msg: can.Message) -> None: ...


class E2eTx:
    def __init__(self, cfg: CanConfig) -> None:
        self.cfg = cfg
        self.codec = E2eCodec()
        self.target_ids = frozenset({self.codec.command.frame_id})
        self.exclusive_ids = self.target_ids
        self.self_checked = True
        self.limit_raw = min(self.codec.limit_raw, self.codec.to_raw(cfg.max_current_A))
        self.to_raw = self.codec.to_raw
        self._last_status_data: bytes | None = None

    def frames(self, cycle: int, raw: int) -> tuple[can.Message, list[can.Message]]:
        return self.codec.command_frame(cycle, raw), []

    def traffic(self) -> list[tuple[int, float]]:
        rate = 1.0 / self.cfg.cycle_period_s
        return [
            (self.codec.command.length, rate),
            (self.codec.status.length, rate / self.cfg.status_every_cycles),
        ]

    def on_reply(self, msg: can.Message) -> None:
        # kept raw: decoding waits until someone asks, off the control loop's time
        if msg.arbitration_id == self.codec.status.frame_id:
            self._last_status_data = bytes(msg.data)

    @property
    def last_status(self) -> DriveStatus | None:
        """The drive's latest intact status frame."""
        data = self._last_status_data
        return None if data is None else self.codec.check_status(data)


class Cia402Tx:
    def __init__(self, cfg: CanConfig) -> None:
        self.cfg = cfg
        self.codec = Cia402Codec(cfg, load_drive_od(cfg.drive_node_id))
        self.target_ids = frozenset({self.codec.rpdo_cob_id})
        # our heartbeat's node id, and SYNC when we produce it, are ours alone too
        own = {self.codec.rpdo_cob_id, self.codec.heartbeat_cob_id}
        self.exclusive_ids = frozenset(
            own | ({self.codec.sync_cob_id} if cfg.sync_master else set())
        )
        self.self_checked = False
        self.limit_raw = min(self.codec.limit_raw, self.codec.to_raw(cfg.max_current_A))
        self.to_raw = self.codec.to_raw
        self.heartbeat_cycles = max(1, round(cfg.heartbeat_period_s / cfg.cycle_period_s))
        self.emcy_received: list[int] = []
        self.drive_heartbeats = 0
        self.syncs_seen = 0  # SYNCs on the bus, whoever produced them
        self.last_sync_s = 0.0  # bus timestamp of the latest

    def frames(self, cycle: int, raw: int) -> tuple[can.Message, list[can.Message]]:
        extra = [self.codec.sync_frame()] if self.cfg.sync_master else []
        if cycle % self.heartbeat_cycles == 0:
            extra.append(self.codec.heartbeat_frame())
        return self.codec.rpdo_frame(raw, cycle), extra

    def traffic(self) -> list[tuple[int, float]]:
        rate = 1.0 / self.cfg.cycle_period_s  # SYNC is on the bus whoever produces it
        return [(3, rate), (0, rate), (1, 1.0 / self.cfg.heartbeat_period_s)]

    def on_reply(self, msg: can.Message) -> None:
        cob_id = msg.arbitration_id
        if cob_id == self.codec.sync_cob_id:
            self.syncs_seen += 1
            self.last_sync_s = msg.timestamp
        elif cob_id == 0x80 + self.cfg.drive_node_id and len(msg.data) >= 2:
            self.emcy_received.append(int.from_bytes(msg.data[:2], "little"))
        elif cob_id == 0x700 + self.cfg.drive_node_id and msg.data[:1] != _BOOTUP:
            self.drive_heartbeats += 1


def make_tx(cfg: CanConfig) -> CompensatorTx:
    return E2eTx(cfg) if cfg.profile == "e2e" else Cia402Tx(cfg)


def profile_bus_load(cfg: CanConfig, tx: CompensatorTx) -> float:
    """Worst-case load of the profile's traffic plus the configured background."""
    return bus_load(tx.traffic(), cfg.bitrate_bit_s) + cfg.background_load


@dataclass
class Shaper:
    """Saturation and ramp-to-zero of the commanded value, in raw CAN units."""

    limit_raw: int
    ramp_cycles: int
    value_raw: int = 0

    def step(self, raw: int | None) -> int:
        """Next command; ``None`` asks for the ramp towards zero (stop or fault)."""
        if raw is None:
            step = math.ceil(self.limit_raw / self.ramp_cycles)
            self.value_raw = toward_zero(self.value_raw, step)
        else:
            self.value_raw = saturate(raw, self.limit_raw)
        return self.value_raw


class Sender(Protocol):
    def send(self, msg: can.Message, timeout: float | None = None) -> None: ...

    def recv(self, timeout: float | None = None) -> can.Message | None: ...


@dataclass
class Streamer:
    """Encodes and sends the feedforward of one control cycle."""

    cfg: CanConfig
    bus: Sender
    tx: CompensatorTx
    frames_sent: int = 0
    send_errors: int = 0
    source_faults: int = 0
    foreign_frames: int = 0  # frames with our exclusive ids sent by another node
    sent_log: list[tuple[float, float, bytes]] = field(default_factory=list)
    send_clock: Callable[[], float] | None = None  # stamps the log at the send, if given

    def __post_init__(self) -> None:
        self.shaper = Shaper(self.tx.limit_raw, self.cfg.ramp_cycles)

    def cycle(self, cycle: int, current_A: float | None, now_s: float) -> int:
        """Send cycle ``cycle``'s frames; ``None`` ramps towards zero. Returns the raw command."""
        if current_A is not None and not math.isfinite(current_A):
            self.source_faults += 1
            current_A = None
        raw = self.shaper.step(None if current_A is None else self.tx.to_raw(current_A))
        feedforward, extra = self.tx.frames(cycle, raw)
        # stamped on both sides of the send: the frame entered the bus in between,
        # however long the thread waited (GIL, scheduler) around the call
        before = now_s if self.send_clock is None else self.send_clock()
        try:
            self.bus.send(feedforward)
            self.frames_sent += 1
            after = now_s if self.send_clock is None else self.send_clock()
            self.sent_log.append((before, after, bytes(feedforward.data)))
            for msg in extra:
                self.bus.send(msg)
        except can.CanError:
            self.send_errors += 1  # the bus is off; the drive's timeout takes over
        self.drain_replies()
        return raw

    def drain_replies(self) -> None:
        """Hand every frame waiting on the bus to the profile; count another node's."""
        while (msg := self.bus.recv(timeout=0.0)) is not None:
            if msg.arbitration_id in self.tx.exclusive_ids:
                self.foreign_frames += 1
            self.tx.on_reply(msg)


def check_channel_free(bus: Sender, cfg: CanConfig, tx: CompensatorTx, listen_s: float) -> None:
    """Refuse to stream if another node already sends our frames on the channel.

    One compensator per drive: listens ``listen_s`` for frames with the ids
    only this compensator may send (the feedforward frame; cia402 also its
    heartbeat and, as SYNC master, SYNC) and raises :class:`BusError` on the first.

    Parameters
    ----------
    bus
        The compensator's bus, before it sends anything.
    cfg, tx
        The ``[can]`` section and the profile's sending side.
    listen_s
        How long to listen; several cycles of the other node's stream.
    """
    deadline = time.monotonic() + listen_s
    while (remaining := deadline - time.monotonic()) > 0:
        msg = bus.recv(timeout=remaining)
        if msg is not None and msg.arbitration_id in tx.exclusive_ids:
            raise BusError(
                f"another node already sends frame 0x{msg.arbitration_id:03X} on "
                f"{cfg.interface} channel {cfg.channel!r} (profile {cfg.profile}, drive node "
                f"{cfg.drive_node_id}): one compensator per drive, stop the other one first"
            )


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
        Cycles a fresh frame takes from the send to its application: 0 stepped,
        1 in real time (the drive applies at its next cycle), plus one when the
        RPDO waits for the next SYNC.

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
        age_cycles = (t - ends[i - 1]) / period_s - transport_cycles
        bad += not is_fresh(age_cycles, max_age_cycles)
    return bad
