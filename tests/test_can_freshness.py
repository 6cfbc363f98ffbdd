"""The one definition of a stale frame, at its boundary, for the drive side and the audit.

Expectations are built from the rule itself (age = drive cycles after the
frame's own cycle; fresh iff age <= max_age_cycles, boundary included), not
from the code's output.
"""

from __future__ import annotations

import pytest

from firmware_bridge.freshness import REANCHOR_FRAMES, FrameClock, is_fresh
from firmware_bridge.streamer import count_unsent_applied
from firmware_bridge.supervisor import Verdict


def anchored_clock(max_age: int) -> FrameClock:
    clock = FrameClock(max_age)
    assert clock.judge(0) is Verdict.RESYNC  # frame 0 dates drive cycle 0
    return clock


@pytest.mark.parametrize("max_age", [0, 1, 2, 5])
def test_frame_exactly_at_the_window_is_applied_one_cycle_more_is_stale(max_age: int) -> None:
    for late_by, expected in ((max_age, Verdict.ACCEPTED), (max_age + 1, Verdict.STALE)):
        clock = anchored_clock(max_age)
        for _ in range(1 + late_by):  # frame 1 belongs to drive cycle 1
            clock.tick()
        assert clock.judge(1) is expected


def test_lag_does_not_accumulate_over_accepted_frames() -> None:
    """Each frame one cycle later than the last: the second is two cycles old, stale.

    (A receiver that re-dates from each accepted frame's arrival let this drift through.)
    """
    clock = anchored_clock(1)
    clock.tick()
    clock.tick()  # cycle 2
    assert clock.judge(1) is Verdict.ACCEPTED  # age 1
    clock.tick()
    clock.tick()  # cycle 4
    assert clock.judge(2) is Verdict.STALE  # age 2


def test_an_early_frame_moves_a_late_anchor() -> None:
    clock = FrameClock(1)
    for _ in range(3):
        clock.tick()
    assert clock.judge(0) is Verdict.RESYNC  # frame 0 arrived 3 cycles late: anchor late
    assert clock.judge(3) is Verdict.ACCEPTED  # on time, so "3 cycles early": anchor moves
    clock.tick()
    clock.tick()
    clock.tick()  # cycle 6: frame 4 is 2 cycles old by the corrected anchor
    assert clock.judge(4) is Verdict.STALE


def test_the_anchor_outlives_a_lost_link() -> None:
    clock = anchored_clock(1)
    for _ in range(100):
        clock.tick()
    clock.link_lost()
    assert clock.judge(98) is Verdict.STALE  # sent 2 cycles ago
    assert clock.judge(100) is Verdict.ACCEPTED  # the first frame after an outage


def test_a_restarted_sender_is_re_anchored_after_a_steady_run_without_applying() -> None:
    clock = anchored_clock(1)
    for _ in range(50):
        clock.tick()
    clock.link_lost()  # the restart took longer than the drive's timeout
    verdicts = []
    for counter in range(REANCHOR_FRAMES + 2):  # a new compensator counting from 0 again
        verdicts.append(clock.judge(counter))
        clock.tick()
    assert verdicts[: REANCHOR_FRAMES - 1] == [Verdict.STALE] * (REANCHOR_FRAMES - 1)
    assert verdicts[REANCHOR_FRAMES - 1] is Verdict.RESYNC
    assert verdicts[REANCHOR_FRAMES:] == [Verdict.ACCEPTED] * 2


def test_float_boundary_is_inclusive_with_a_tolerance() -> None:
    # the audit's case from issue 13: 3.0000000000000027 ms against a 3 ms window
    assert is_fresh(3.0000000000000027e-3 / 1e-3, 3)
    assert is_fresh(3, 3) and not is_fresh(3.001, 3) and not is_fresh(4, 3)


@pytest.mark.parametrize("transport", [0, 1, 2])
def test_audit_flags_a_frame_one_cycle_past_the_window(transport: int) -> None:
    period, max_age, k = 1e-3, 1, 37
    sent = [(k * period, k * period, b"a")]
    at_window = (k + max_age + transport) * period  # float noise as in a real run
    assert count_unsent_applied(sent, [(at_window, b"a")], period, max_age, transport) == 0
    late = (k + max_age + transport + 1) * period
    assert count_unsent_applied(sent, [(late, b"a")], period, max_age, transport) == 1
    assert count_unsent_applied(sent, [(at_window, b"b")], period, max_age, transport) == 1
    before = (k - 1) * period  # applied before it was sent
    assert count_unsent_applied(sent, [(before, b"a")], period, max_age, transport) == 1


def test_a_long_silence_after_the_last_frame_does_not_block_newer_frames() -> None:
    """200 cycles on (more than half the counter range): the new frame is fresh, not
    'older' by a wrapped counter difference."""
    clock = anchored_clock(1)
    for _ in range(200):
        clock.tick()
    assert clock.judge(200) is Verdict.ACCEPTED
    assert clock.judge(199) is Verdict.OUT_OF_ORDER  # older than the last, still recent
