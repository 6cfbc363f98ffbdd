"""The SYNC counter: a SYNC follower numbers its frames by the NC's time slots.

By timestamps alone, a SYNC sent more than half a cycle late looks like the next
slot's SYNC on time, and since a follower never reuses a counter, every later
frame then claims a slot one cycle ahead of time: younger than it is to the
drive, which could apply it a cycle past the validity window. The CiA 301 SYNC
counter (one byte, 1..240) says which slot a late SYNC belongs to.
"""

from __future__ import annotations

import itertools
import math
import threading
import time
from types import SimpleNamespace

import can
import pytest

from firmware_bridge import realtime as session
from firmware_bridge.profiles.base import SYNC_COUNTER_OVERFLOW, SyncCounter, sync_slot
from firmware_bridge.profiles.cia402 import nc
from firmware_bridge.profiles.cia402.codec import Cia402Codec, load_drive_od
from firmware_bridge.profiles.cia402.nc import SyncProducer
from firmware_bridge.settings import CanConfig


def test_a_late_sync_keeps_its_slot_by_its_counter() -> None:
    # slots 0, 1, 2 at t = 0, 1.6, 2.0 periods: the second was 0.6 late
    assert sync_slot(0, None, None, round(1.6)) == 2  # by time: taken for slot 2
    assert sync_slot(0, 1, 2, round(1.6)) == 1  # by counter: slot 1
    assert sync_slot(1, 2, 3, round(2.0)) == 2  # and the next is on time again


def test_a_skipped_sync_shows_as_a_gap_in_the_counter() -> None:
    assert sync_slot(10, 11, 13, 12) == 12
    assert sync_slot(10, 11, 13, 13) == 12  # and late besides


def test_the_counter_wraps_and_time_resolves_whole_wraps() -> None:
    last = SYNC_COUNTER_OVERFLOW
    assert sync_slot(239, last, 1, 240) == 240
    # 1 + 240 slots of silence: the counter alone says 1, the time says 241
    assert sync_slot(100, 5, 6, 100 + 1 + SYNC_COUNTER_OVERFLOW) == 101 + SYNC_COUNTER_OVERFLOW


def test_a_repeated_counter_never_goes_back() -> None:
    assert sync_slot(7, 8, 8, 7) == 8


def test_sync_counter_reads_the_byte_and_none_without_it() -> None:
    seen = SyncCounter()
    seen.saw(1.0, bytes([17]))
    assert (seen.seen, seen.last_counter) == (1, 17)
    seen.saw(2.0)
    assert seen.last_counter is None


@pytest.mark.parametrize("late_wakeups", [0, 3])
def test_nc_counts_its_grid_slots_including_the_ones_it_skipped(
    late_wakeups: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """SyncProducer on a fake clock: the counter follows the grid, 1..240 and round."""
    monkeypatch.setattr(nc.time, "sleep", lambda _s: None)  # the fake clock is the time
    cfg = CanConfig()
    codec = Cia402Codec(cfg, load_drive_od(cfg.drive_node_id))
    with can.Bus(interface="virtual", channel="sync-counter", receive_own_messages=True) as bus:
        producer = SyncProducer(bus, codec, 1e-3)
        now = [0.0]
        stop = threading.Event()
        sent: list[int] = []

        def clock() -> float:
            return now[0]

        def send() -> None:
            sent.append(producer.slot)
            SyncProducer.send(producer)
            # each send takes a quarter period; a late wake-up loses 2.5 periods
            now[0] += 0.25e-3 + (2.5e-3 if len(sent) <= late_wakeups else 0.0)
            if len(sent) >= 300:
                stop.set()

        producer.send = send  # type: ignore[method-assign]
        producer.run(stop, clock)
        counters = []
        while (msg := bus.recv(timeout=0.0)) is not None:
            counters.append(msg.data[0])
    assert counters == [slot % SYNC_COUNTER_OVERFLOW + 1 for slot in sent]
    assert sent[: late_wakeups + 1] == [3 * k for k in range(late_wakeups + 1)]
    steady = sent[late_wakeups:]
    assert all(b - a == 1 for a, b in itertools.pairwise(steady))
    assert max(counters) == SYNC_COUNTER_OVERFLOW and min(counters) == 1


def test_a_late_wake_up_sends_the_slot_it_is_in_not_an_old_number(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Sleep overshoots by 2.6 periods every 7th wake-up: each SYNC carries the slot of
    the time it is sent (floor(t / period)), never the number of a slot already over."""
    period = 1e-3
    now = [0.0]
    wakeups = [0]

    def sleep(seconds: float) -> None:
        wakeups[0] += 1
        now[0] += seconds + (2.6 * period if wakeups[0] % 7 == 0 else 0.0)

    monkeypatch.setattr(nc.time, "sleep", sleep)
    cfg = CanConfig()
    codec = Cia402Codec(cfg, load_drive_od(cfg.drive_node_id))
    with can.Bus(interface="virtual", channel="sync-late-wakeup") as bus:
        producer = SyncProducer(bus, codec, period)
        stop = threading.Event()
        sent: list[tuple[int, float]] = []

        def send() -> None:
            sent.append((producer.slot, now[0]))
            SyncProducer.send(producer)
            now[0] += 0.1 * period
            if len(sent) >= 100:
                stop.set()

        producer.send = send  # type: ignore[method-assign]
        producer.run(stop, lambda: now[0])
    assert wakeups[0] >= 14  # some wake-ups were late
    assert all(slot == math.floor(t / period + 1e-9) for slot, t in sent)


def test_a_follower_behind_answers_the_latest_sync_only() -> None:
    """Three SYNCs queued while the loop was away: it takes them all, answers the last."""
    cfg = CanConfig()
    codec = Cia402Codec(cfg, load_drive_od(cfg.drive_node_id))
    queued = [codec.sync_frame(c) for c in (5, 6, 7)]
    sync = SyncCounter()

    class Faulty:
        def recv(self, timeout: float | None = None) -> can.Message | None:
            return queued.pop(0) if queued else None

    class Streamer:
        def take_reply(self, msg: can.Message, now_s: float) -> None:
            sync.saw(0.0, bytes(msg.data))

    rig = SimpleNamespace(faulty=Faulty(), streamer=Streamer())
    assert session._await_sync(rig, sync, 0, 1.0, time.monotonic)  # type: ignore[arg-type]
    assert (sync.seen, sync.last_counter) == (3, 7)
