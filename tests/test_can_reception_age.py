"""The second freshness rule: a drive on its own clock dates a frame by time too.

The alive counter dates a frame by the cycle it was made for, against an anchor
in whole drive cycles; a frame held up after it arrived (an RPDO waiting for a
SYNC the compensator was descheduled before sending), or held up on the way
after leaving early in its cycle, can be up to a cycle older than the counter
says. At the moment it would be applied, the drive refuses a frame whose
``(apply - sent) / period - transport`` exceeds the window: the audit's rule,
with ``sent`` the earliest the frame can have left: its reception, or its slot
(the earliest reception so far, relative to the counter) less a margin of 0.25
cycle in real time, whichever is earlier. Expectations are worked out by hand
from that rule (window 1 cycle, transport 1 in real time).
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import can
import pytest

from firmware_bridge.emulator import DriveEmulator
from firmware_bridge.freshness import FrameClock, age_by_time, transport_cycles
from firmware_bridge.profiles.cia402.codec import Cia402Codec, load_drive_od
from firmware_bridge.profiles.e2e.codec import E2eCodec
from firmware_bridge.profiles.e2e.receiver import E2eReceiver
from firmware_bridge.settings import CanConfig
from firmware_bridge.streamer import count_unsent_applied, make_tx, profile_bus_load
from firmware_bridge.supervisor import Supervisor, Verdict

P = 1e-3  # the cycle
_channels = itertools.count()


def test_transport_is_defined_once_for_drive_and_audit() -> None:
    assert transport_cycles(real_time=False, waits_for_sync=False) == 0
    assert transport_cycles(real_time=True, waits_for_sync=False) == 1
    assert transport_cycles(real_time=True, waits_for_sync=True) == 2
    assert transport_cycles(real_time=False, waits_for_sync=True) == 1


def test_age_by_time_at_and_past_the_window() -> None:
    clock = FrameClock(1, P, transport_cycles=1)
    assert age_by_time(3e-3, 1e-3, P, 1) == pytest.approx(1.0)
    assert not clock.outlived(1e-3, 3e-3)  # 2 cycles on the way: 1 transport + 1 of age
    assert clock.outlived(1e-3, 3.01e-3)
    assert not FrameClock(1).outlived(0.0, 1.0)  # without a period: no rule by time


def cia402_drive() -> tuple[DriveEmulator, Cia402Codec, can.BusABC]:
    cfg = replace(CanConfig(), channel=f"test-reception-{next(_channels)}", max_frame_age_cycles=1)
    bus = can.Bus(interface="virtual", channel=cfg.channel)
    drive = DriveEmulator(cfg, bus)
    drive.side.set_real_time(True)
    return drive, Cia402Codec(cfg, load_drive_od(cfg.drive_node_id)), bus


@pytest.mark.parametrize(("received_s", "applied"), [(2.25e-3, True), (1.6e-3, False)])
def test_an_rpdo_held_before_its_sync_past_the_window_is_refused(
    received_s: float, applied: bool
) -> None:
    """The anchor frame arrives late in its cycle, so the counter has a cycle of slack.

    Frame 0 (RPDO and SYNC) at 1.5 ms, after the drive's tick at 1 ms: counter 0
    belongs to drive cycle 1. Frame 1 arrives at ``received_s``, its SYNC only at
    3.7 ms: by the counter it is 1 cycle old there (3 ticks done, minus counter 1,
    minus the anchor 1), fresh. Its slot is 2.5 ms (frame 0's reception plus one
    cycle); it came earlier, so the drive dates it from its reception less the 0.25 ms
    margin. It would be applied at the 4 ms tick: 2.0 ms after 2.0 ms for a reception
    at 2.25 ms (exactly the window plus transport: applied), 2.65 ms after 1.35 ms for
    one at 1.6 ms (0.65 cycle past: refused as stale).
    """
    drive, codec, bus = cia402_drive()
    with bus:
        ticks = iter([1e-3, 2e-3, 3e-3, 4e-3])
        drive.tick(0.0)
        drive.tick(next(ticks))
        drive.handle(codec.rpdo_frame(100, 0), 1.5e-3)
        drive.handle(codec.sync_frame(), 1.5e-3)
        drive.tick(next(ticks))  # 2 ms
        drive.handle(codec.rpdo_frame(200, 1), received_s)
        drive.tick(next(ticks))  # 3 ms
        drive.handle(codec.sync_frame(), 3.7e-3)
        drive.tick(next(ticks))  # 4 ms: frame 1 is applied now or never
        counts = drive.counts.counts
        assert counts[Verdict.RESYNC] == 1
        if applied:
            assert drive.applied_log == [(4e-3, bytes(codec.rpdo_frame(200, 1).data))]
            assert (counts[Verdict.ACCEPTED], counts[Verdict.STALE]) == (1, 0)
        else:
            assert drive.applied_log == []
            assert (counts[Verdict.ACCEPTED], counts[Verdict.STALE]) == (0, 1)
        # the audit, with the send ending at the reception, agrees
        sent = [(received_s, received_s, bytes(codec.rpdo_frame(200, 1).data))]
        audited = [(4e-3, sent[0][2])]
        assert count_unsent_applied(sent, audited, P, 1, transport_cycles(True, False)) == (
            0 if applied else 1
        )


def e2e_frame(codec: E2eCodec, counter: int, raw: int) -> bytes:
    return codec.encode_command(counter, raw)


@pytest.mark.parametrize(("apply_s", "applied"), [(2.35e-3, True), (2.36e-3, False)])
def test_e2e_frame_refused_when_its_cycle_comes_too_late(apply_s: float, applied: bool) -> None:
    """Received at 0.6 ms, before its slot (1 ms, a cycle after frame 0): fresh by its counter,
    dated from 0.35 ms (its reception less the margin). Its drive cycle comes at ``apply_s``:
    at 2.35 ms it is 1 cycle old after the 1 of transport (applied), at 2.36 ms it is past."""
    codec = E2eCodec()
    receiver = E2eReceiver(codec, Supervisor(10_000, 3, 5), max_age_cycles=1, period_s=P)
    receiver.set_real_time(True)
    assert receiver.on_frame(e2e_frame(codec, 0, 5), 0.0) is Verdict.RESYNC
    receiver.tick(0.5e-3)
    assert receiver.on_frame(e2e_frame(codec, 1, 7), 0.6e-3) is Verdict.ACCEPTED
    out = receiver.tick(apply_s)
    assert (out == 7) is applied
    assert receiver.counts.counts[Verdict.STALE] == (0 if applied else 1)


@pytest.mark.parametrize(
    ("phase_ms", "sent_ms", "received_ms", "applied"),
    [
        (0.05, 1.99, 3.95, False),  # left before its slot, held: 1.01 cycles old (stale)
        (0.05, 2.30, 3.90, False),  # left after its slot: 0.7 cycle old, but the margin
        (0.50, 2.60, 3.90, True),  # the slot 0.5 cycle after the tick: 0.75 by the rule
        (0.50, 2.40, 3.90, True),  # 0.1 cycle before its slot: 0.6 old, 0.75 by the rule
    ],
)
def test_e2e_held_frame_dated_by_its_slot_less_the_margin(
    phase_ms: float, sent_ms: float, received_ms: float, applied: bool
) -> None:
    """A frame held up on the way, fresh by its counter, is dated by its slot less 0.25 cycle.

    Frames 0 and 1 arrive on time, ``phase_ms`` after the drive's ticks at 0 and 1 ms:
    the slot of counter 2 is at 2 ms + ``phase_ms``. Frame 2 leaves at ``sent_ms``,
    is held and arrives at ``received_ms`` in the cycle begun at 3 ms: counter age
    3 - 2 = 1, fresh by the counter (window 1). It would be applied at the 4 ms tick,
    ``4 - sent_ms - 1`` cycles old by the audit's clock. By the time rule it is
    ``4 - (2 + phase_ms - 0.25) - 1 = 1.25 - phase_ms`` old: refused when the
    compensator's cycles begin within 0.25 cycle after the drive's ticks, where the
    counter cannot tell whether a frame left just before or just after a tick (the
    first row: 0.01 cycle past the window, which the counter alone let through).
    """
    codec = E2eCodec()
    receiver = E2eReceiver(codec, Supervisor(10_000, 3, 5), max_age_cycles=1, period_s=P)
    receiver.set_real_time(True)
    phase = phase_ms * 1e-3
    assert receiver.on_frame(e2e_frame(codec, 0, 5), phase) is Verdict.RESYNC
    receiver.tick(1e-3)
    assert receiver.on_frame(e2e_frame(codec, 1, 6), 1e-3 + phase) is Verdict.ACCEPTED
    assert receiver.tick(2e-3) == 6
    receiver.tick(3e-3)
    frame = e2e_frame(codec, 2, 7)
    assert receiver.on_frame(frame, received_ms * 1e-3) is Verdict.ACCEPTED  # by the counter
    out = receiver.tick(4e-3)
    assert (out == 7) is applied
    assert receiver.counts.counts[Verdict.STALE] == (0 if applied else 1)
    # whatever the drive applies, the audit (from the send's end) finds fresh
    if applied:
        sent = [(sent_ms * 1e-3, sent_ms * 1e-3, frame)]
        assert count_unsent_applied(sent, [(4e-3, frame)], P, 1, transport_cycles(True, False)) == 0


def test_slot_follows_the_earliest_frame_and_unwraps_the_counter() -> None:
    """The slot moves only earlier, and a counter that wrapped is placed by time."""
    clock = FrameClock(3, P, transport_cycles=1, slot_margin_cycles=0.25)
    assert clock.judge(250, 0.4e-3) is Verdict.RESYNC  # slot of 250: 0.4 ms
    for k in range(1, 10):  # on time, 0.1 ms later in their cycles than frame 250
        clock.tick()
        counter = (250 + k) % 256
        assert clock.judge(counter, 0.5e-3 + k * P) is Verdict.ACCEPTED
        assert clock.sent_by(counter, 0.5e-3 + k * P) == pytest.approx(0.15e-3 + k * P)
    clock.tick()
    assert clock.judge(4, 10.2e-3) is Verdict.ACCEPTED  # counter 260 = 4 after the wrap, early
    assert clock.sent_by(4, 10.2e-3) == pytest.approx(9.95e-3)  # the slot moved to it
    assert clock.sent_by(3, 12e-3) == pytest.approx(8.95e-3)  # held frame: its slot, not 12 ms


def test_bus_load_counts_the_nc_sync_counter_byte() -> None:
    """The NC's SYNC carries the one-byte counter: 8 data bits and, at worst, 2 more stuff
    bits (34 -> 42 stuffed bits: 8 -> 10 stuff bits) per SYNC, 1000 SYNCs per s at 1 Mbit/s."""
    master = replace(CanConfig(), profile="cia402")
    follower = replace(master, sync_master=False)
    extra = profile_bus_load(follower, make_tx(follower)) - profile_bus_load(
        master, make_tx(master)
    )
    assert extra == pytest.approx(10 * 1000 / 1_000_000)
