"""The CiA 402 power state machine, against the standard's transition table.

Expectations are the device-control states of CiA 402 (IEC 61800-7-201): the enable
sequence 0x06, 0x07, 0x0F; "disable voltage" (bit 1 clear) to switch on disabled; quick
stop (bit 2 clear) from operation to quick stop active; a fault left only by a rising
edge of bit 7; and the statusword bit patterns that show each state.
"""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from firmware_bridge.profiles.cia402.statemachine import (
    ENABLE_SEQUENCE,
    PowerState,
    PowerStateMachine,
    state_of,
)

S = PowerState


def test_the_enable_sequence_reaches_operation_enabled() -> None:
    sm = PowerStateMachine()
    assert sm.state is S.SWITCH_ON_DISABLED and not sm.enabled
    seen = [sm.command(cw) for cw in ENABLE_SEQUENCE]
    assert seen == [S.READY_TO_SWITCH_ON, S.SWITCHED_ON, S.OPERATION_ENABLED]
    assert sm.enabled


def test_statusword_patterns_are_the_standards() -> None:
    # CiA 402 statusword, bits 0-3, 5, 6 (x = don't care): 0x0040 switch on disabled,
    # 0x0021 ready to switch on, 0x0023 switched on, 0x0027 operation enabled,
    # 0x0007 quick stop active, 0x0008 fault; bit 9 remote
    masks = {
        S.SWITCH_ON_DISABLED: (0x4F, 0x40),
        S.READY_TO_SWITCH_ON: (0x6F, 0x21),
        S.SWITCHED_ON: (0x6F, 0x23),
        S.OPERATION_ENABLED: (0x6F, 0x27),
        S.QUICK_STOP_ACTIVE: (0x6F, 0x07),
        S.FAULT: (0x4F, 0x08),
    }
    for state, (mask, value) in masks.items():
        sm = PowerStateMachine(state=state)
        assert sm.statusword & mask == value
        assert sm.statusword & 0x0200  # remote
        assert state_of(sm.statusword) is state


def test_quick_stop_and_disable_voltage_leave_operation() -> None:
    sm = PowerStateMachine(state=S.OPERATION_ENABLED)
    assert sm.command(0x0B) is S.QUICK_STOP_ACTIVE  # bit 2 clear
    assert sm.command(0x00) is S.SWITCH_ON_DISABLED  # bit 1 clear
    sm = PowerStateMachine(state=S.OPERATION_ENABLED)
    assert sm.command(0x07) is S.SWITCHED_ON  # disable operation


def test_a_fault_is_left_only_by_a_rising_fault_reset() -> None:
    sm = PowerStateMachine(state=S.OPERATION_ENABLED)
    sm.fault(0x8611)
    assert sm.state is S.FAULT and sm.fault_code == 0x8611
    for cw in ENABLE_SEQUENCE:
        assert sm.command(cw) is S.FAULT
    assert sm.command(0x80) is S.SWITCH_ON_DISABLED  # rising edge of bit 7
    assert sm.fault_code == 0
    sm.fault(0x8100)
    assert sm.command(0x80) is S.FAULT  # bit 7 still set: no rising edge
    assert sm.command(0x00) is S.FAULT
    assert sm.command(0x80) is S.SWITCH_ON_DISABLED


@given(st.lists(st.integers(0, 0xFF), max_size=40))
def test_operation_is_only_reached_through_switched_on(controlwords: list[int]) -> None:
    sm = PowerStateMachine()
    previous = sm.state
    for cw in controlwords:
        state = sm.command(cw)
        if state is S.OPERATION_ENABLED and previous is not S.OPERATION_ENABLED:
            assert previous is S.SWITCHED_ON
        previous = state


@given(st.lists(st.integers(0, 0x7F), max_size=40))
def test_without_bit_7_a_fault_never_ends(controlwords: list[int]) -> None:
    sm = PowerStateMachine()
    sm.fault(0x8100)
    for cw in controlwords:
        assert sm.command(cw) is S.FAULT
