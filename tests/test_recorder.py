"""The per-SYNC recorder: rows filed by the SYNC each TPDO answers; lost and late counted.

Frames are built here byte by byte from the EDS's PDO layouts (0x6041, 0x2002, 0x2005,
0x6078, 0x2006 in TPDO1; 0x6064, 0x606C in TPDO2), not through the drive.
"""

from __future__ import annotations

import math
import struct

import can
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_bridge.profiles.cia402.codec import Cia402Codec, load_drive_od
from firmware_bridge.profiles.cia402.recorder import Recorder
from firmware_bridge.settings import CanConfig

UNIT = 1e-9
RATED = 2.0
CODEC = Cia402Codec(CanConfig(rated_current_A=RATED), load_drive_od(1))


def tpdo1(counter: int, current_permille: int) -> can.Message:
    data = struct.pack("<HHBhB", 0x0237, 0, 5, current_permille, counter)
    return can.Message(arbitration_id=0x181, data=data, is_extended_id=False)


def tpdo2(position_inc: int, velocity_inc: int) -> can.Message:
    data = struct.pack("<ii", position_inc, velocity_inc)
    return can.Message(arbitration_id=0x281, data=data, is_extended_id=False)


def test_each_row_gets_its_own_sync_answer_and_the_previous_target() -> None:
    rec = Recorder(CODEC, UNIT, RATED)
    for slot in range(4):
        rec.sync(slot, slot + 1, target_m=1e-6 * slot)
        rec.frame(tpdo1(slot + 1, 100 * slot))
        rec.frame(tpdo2(1000 * slot, 7))
    r = rec.finish()
    assert r.slots == [0, 1, 2, 3]
    assert math.isnan(r.rows[0][0])  # no SYNC before the first: no target followed
    assert [row[0] for row in r.rows[1:]] == pytest.approx([0.0, 1e-6, 2e-6])
    assert [row[1] for row in r.rows] == pytest.approx([0.0, 1e-6, 2e-6, 3e-6])
    assert [row[3] for row in r.rows] == pytest.approx([0.0, 0.2, 0.4, 0.6])  # per mille of 2 A
    assert r.late == 0 and r.lost == {"status": 0, "motion": 0, "target": 1}


def test_a_late_tpdo_is_filed_under_its_sync_and_counted_late() -> None:
    rec = Recorder(CODEC, UNIT, RATED)
    rec.sync(0, 1, 0.0)
    rec.sync(1, 2, 0.0)  # SYNC 1's TPDOs come only after SYNC 2
    rec.frame(tpdo1(1, 50))
    rec.frame(tpdo2(11, 0))
    rec.frame(tpdo1(2, 60))
    rec.frame(tpdo2(22, 0))
    r = rec.finish()
    assert [row[1] for row in r.rows] == pytest.approx([11e-9, 22e-9])
    assert r.late == 1


def test_a_lost_tpdo_leaves_nan_and_is_counted() -> None:
    rec = Recorder(CODEC, UNIT, RATED)
    rec.sync(0, 1, 0.0)
    rec.frame(tpdo2(5, 0))  # its TPDO1 was lost: the TPDO2 has no row to go to
    rec.sync(1, 2, 0.0)
    rec.frame(tpdo1(2, 10))
    rec.frame(tpdo2(6, 0))
    r = rec.finish()
    assert math.isnan(r.rows[0][1]) and math.isnan(r.rows[0][3])
    assert r.rows[1][1] == pytest.approx(6e-9)
    assert r.lost["status"] == 1 and r.lost["motion"] == 1


def test_a_skipped_sync_slot_is_a_missing_sample_on_the_time_grid() -> None:
    rec = Recorder(CODEC, UNIT, RATED)
    for slot in (0, 1, 3):  # the master's loop was late for slot 2
        rec.sync(slot, slot + 1, 0.0)
        rec.frame(tpdo1(slot + 1, 0))
        rec.frame(tpdo2(slot, 0))
    r = rec.finish()
    position = r.column("position_m")
    assert position.size == 4 and math.isnan(position[2])
    assert list(position[[0, 1, 3]] / UNIT) == pytest.approx([0, 1, 3])


def test_without_a_sync_counter_a_tpdo_goes_to_the_row_open_when_it_arrives() -> None:
    rec = Recorder(CODEC, UNIT, RATED)
    rec.sync(0, 0, 0.0)
    rec.frame(tpdo1(0, 20))
    rec.frame(tpdo2(9, 0))
    r = rec.finish()
    assert r.rows[0][1] == pytest.approx(9e-9) and r.rows[0][3] == pytest.approx(0.04)


@settings(max_examples=50, deadline=None, derandomize=True)
@given(st.lists(st.booleans(), min_size=2, max_size=60))
def test_a_row_holds_the_target_of_the_slot_just_before_or_none(seen: list[bool]) -> None:
    """Along a moving target (slot k brings k um), SYNCs skipped at random (an NC or a bus
    that stalled): a row's target is the one of its slot's predecessor, never one from
    before a stall, and every row after a stall is counted without a target."""
    rec = Recorder(CODEC, UNIT, RATED)
    slots = [k for k, s in enumerate(seen) if s] or [0]
    for k in slots:
        rec.sync(k, k % 240 + 1, target_m=1e-6 * k)
    r = rec.finish()
    for slot, row in zip(r.slots, r.rows, strict=True):
        if slot - 1 in slots:
            assert row[0] == pytest.approx(1e-6 * (slot - 1))
        else:
            assert math.isnan(row[0])
    assert r.lost["target"] == sum(k - 1 not in slots for k in slots)
