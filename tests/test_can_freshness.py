"""The one definition of a fresh frame and the session claim, for the drive side and the audit.

Expectations come from the rule itself (fresh at drive cycle ``n`` iff
``0 <= n - stamp <= max_age``; one session held at a time), and, for the claim that
no delay can make a late frame look fresh, from a simulation in continuous time whose
audit measures ages by the wall clock, not by the code's stamps.
"""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_bridge.freshness import (
    SESSION_TIMEOUT_FACTOR,
    STAMP_MODULUS,
    DriveClock,
    DriveTime,
    Mode,
    is_fresh,
    session_timeout_cycles,
    stamp_age,
)
from firmware_bridge.streamer import count_unsent_applied
from firmware_bridge.supervisor import Verdict

SESSION = 5


def granted_clock(max_age: int) -> DriveClock:
    clock = DriveClock(max_age)
    assert clock.judge(0, SESSION, Mode.REQUEST) is Verdict.GRANTED
    return clock


@pytest.mark.parametrize("max_age", [0, 1, 2, 5])
def test_a_command_exactly_at_the_window_is_taken_one_cycle_more_is_stale(max_age: int) -> None:
    for late_by, expected in ((max_age, Verdict.ACCEPTED), (max_age + 1, Verdict.STALE)):
        clock = granted_clock(max_age)
        for _ in range(1 + late_by):
            clock.advance()
        assert clock.judge(1, SESSION, Mode.COMMAND) is expected


def test_a_frame_dated_in_the_drives_future_is_early() -> None:
    clock = granted_clock(1)
    assert clock.judge(1, SESSION, Mode.COMMAND) is Verdict.EARLY


def test_stamps_wrap_at_16_bits() -> None:
    assert stamp_age(3, STAMP_MODULUS - 2) == 5
    assert stamp_age(STAMP_MODULUS - 2, 3) == -5
    clock = DriveClock(1, cycle=STAMP_MODULUS - 1)
    assert clock.judge(STAMP_MODULUS - 1, SESSION, Mode.REQUEST) is Verdict.GRANTED
    clock.advance()  # cycle 0 again
    assert clock.judge(0, SESSION, Mode.COMMAND) is Verdict.ACCEPTED


def test_commands_must_be_newer_than_the_last_taken() -> None:
    clock = granted_clock(2)
    clock.advance()
    clock.advance()  # cycle 2
    assert clock.judge(2, SESSION, Mode.COMMAND) is Verdict.ACCEPTED
    assert clock.judge(2, SESSION, Mode.COMMAND) is Verdict.DUPLICATE
    assert clock.judge(1, SESSION, Mode.COMMAND) is Verdict.OUT_OF_ORDER


def test_one_session_at_a_time_and_only_a_request_takes_it() -> None:
    clock = DriveClock(1)
    assert clock.judge(0, SESSION, Mode.COMMAND) is Verdict.FOREIGN  # no session granted
    assert clock.judge(0, SESSION, Mode.REQUEST) is Verdict.GRANTED
    assert clock.judge(0, SESSION + 1, Mode.REQUEST) is Verdict.FOREIGN  # a second one
    assert clock.judge(0, SESSION + 1, Mode.COMMAND) is Verdict.FOREIGN
    assert clock.session == SESSION
    assert clock.judge(0, SESSION, Mode.RELEASE) is Verdict.RELEASED
    assert clock.session == 0
    assert clock.judge(0, SESSION + 1, Mode.REQUEST) is Verdict.GRANTED


def test_a_stale_request_takes_no_session() -> None:
    clock = DriveClock(1, cycle=10)
    assert clock.judge(8, SESSION, Mode.REQUEST) is Verdict.STALE
    assert clock.session == 0


@pytest.mark.parametrize("timeout", [1, 3])
def test_a_session_without_frames_for_longer_than_its_timeout_ends(timeout: int) -> None:
    clock = DriveClock(1, session_timeout_cycles=session_timeout_cycles(timeout))
    assert clock.judge(0, SESSION, Mode.REQUEST) is Verdict.GRANTED
    for _ in range(SESSION_TIMEOUT_FACTOR * timeout):
        clock.advance()
        assert clock.session == SESSION
    clock.advance()
    assert clock.session == 0


def test_the_compensator_has_no_date_before_the_drive_speaks_nor_beyond_its_horizon() -> None:
    by_time = DriveTime(1e-3, horizon_cycles=4)
    assert by_time.stamp(0.0) is None
    by_time.observe(100, 0, now_s=1.0)
    assert by_time.stamp(1.0) == 101
    assert by_time.stamp(1.0 + 4.5e-3) == 105  # four whole periods passed
    assert by_time.stamp(1.0 + 5.5e-3) is None  # five: beyond the horizon
    follower = DriveTime(1e-3, horizon_cycles=4, lead_cycles=1)
    follower.observe(7, 0, now_s=0.0)
    assert follower.stamp(0.0) == 9  # its RPDO waits for the next SYNC: one more


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


def simulate(
    status_delays: list[float], frame_delays: list[float], phase: float, max_age: int
) -> tuple[list[tuple[float, float]], int]:
    """In continuous time (unit: one cycle): the drive ticks at n and publishes n; the
    compensator's cycles begin at k + phase, it handles every status delivered by then
    and sends one command stamped by :class:`DriveTime`; each status and each command
    is delivered after its own delay (cycled through the lists). Returns the commands
    the drive took, as (apply time, send time), and how many were sent."""
    cycles = 120
    statuses = sorted((n + status_delays[n % len(status_delays)], n) for n in range(cycles))
    time_ = DriveTime(1.0, horizon_cycles=4)
    sent_at: dict[int, float] = {}
    arrivals: list[tuple[float, int, int]] = []
    for k in range(cycles):
        now = k + phase
        while statuses and statuses[0][0] <= now:
            time_.observe(statuses.pop(0)[1], SESSION, now)
        stamp = time_.stamp(now)
        if stamp is not None:
            sent_at[k] = now
            arrivals.append((now + frame_delays[k % len(frame_delays)], k, stamp))
    arrivals.sort()
    clock = granted_clock(max_age)
    applied: list[tuple[float, float]] = []
    i = 0
    for n in range(cycles + 20):  # the tick at time n applies what arrived before it
        candidate = None
        while i < len(arrivals) and arrivals[i][0] < n:
            _, k, stamp = arrivals[i]
            if clock.judge(stamp, SESSION, Mode.COMMAND) is Verdict.ACCEPTED:
                candidate = k
            i += 1
        if candidate is not None:
            applied.append((float(n), sent_at[candidate]))
        clock.advance()
        clock.idle_cycles = 0  # the session's expiry is not under test here
    return applied, len(sent_at)


delays = st.lists(st.floats(0.0, 12.0), min_size=1, max_size=40)


@settings(max_examples=200, deadline=None)
@given(
    status_delays=delays,
    frame_delays=delays,
    phase=st.floats(0.0, 0.999),
    max_age=st.integers(0, 3),
)
def test_no_delay_of_any_frame_makes_a_late_command_fresh(
    status_delays: list[float], frame_delays: list[float], phase: float, max_age: int
) -> None:
    """Any sustained or varying delay of the statuses and of the commands: every command
    the drive takes is applied at most ``max_age`` cycles after the end of the cycle it
    was sent in, by the wall clock (the audit's transport of one cycle)."""
    applied, _ = simulate(status_delays, frame_delays, phase, max_age)
    for apply_t, send_t in applied:
        assert apply_t - send_t - 1 <= max_age + 1e-9


@pytest.mark.parametrize("phase", [0.05, 0.5, 0.95])
def test_on_a_prompt_link_every_command_is_taken(phase: float) -> None:
    """The property above is not bought by refusing everything: with statuses delivered
    within a fifth of a cycle and commands before the next tick, the drive takes every
    command sent, one a tick."""
    applied, sent = simulate([0.1, 0.2], [0.0, 0.03], phase, max_age=1)
    assert sent >= 119 and len(applied) == sent
