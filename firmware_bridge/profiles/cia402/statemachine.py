"""The CiA 402 power state machine of a drive: controlword in, statusword out.

The device control of CiA 402 (IEC 61800-7-201): the NC moves the drive from "switch on
disabled" through "ready to switch on" and "switched on" to "operation enabled" with the
controlword (0x6040) commands shutdown (0x06), switch on (0x07) and enable operation
(0x0F); disable voltage (bit 1 clear) and quick stop (bit 2 clear) take it back, a fault
takes it to "fault", and a rising edge of bit 7 (fault reset) from there to "switch on
disabled". Only in "operation enabled" does the drive follow the target and apply the
feedforward. The statusword (0x6041) shows the state in its low bits as the standard
defines them, with "remote" (bit 9) always set.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

FAULT_RESET_BIT = 0x80
REMOTE = 0x0200
VOLTAGE_ENABLED = 0x0010


class PowerState(enum.Enum):
    """The device states, with the statusword each shows."""

    SWITCH_ON_DISABLED = 0x0040
    READY_TO_SWITCH_ON = 0x0021 | VOLTAGE_ENABLED
    SWITCHED_ON = 0x0023 | VOLTAGE_ENABLED
    OPERATION_ENABLED = 0x0027 | VOLTAGE_ENABLED
    QUICK_STOP_ACTIVE = 0x0007 | VOLTAGE_ENABLED
    FAULT = 0x0008


SHUTDOWN, SWITCH_ON, ENABLE_OPERATION, DISABLE_VOLTAGE = 0x06, 0x07, 0x0F, 0x00
"""The controlword commands an NC sends (bit 7 clear)."""
ENABLE_SEQUENCE = (SHUTDOWN, SWITCH_ON, ENABLE_OPERATION)


@dataclass
class PowerStateMachine:
    """The drive's state, moved by controlwords and faults."""

    state: PowerState = PowerState.SWITCH_ON_DISABLED
    fault_code: int = 0
    _last_controlword: int = 0

    @property
    def statusword(self) -> int:
        """0x6041 for the current state."""
        return self.state.value | REMOTE

    @property
    def enabled(self) -> bool:
        """The drive follows the target and applies the feedforward."""
        return self.state is PowerState.OPERATION_ENABLED

    def fault(self, code: int) -> None:
        """A fault (an EMCY code): the drive leaves operation until a fault reset."""
        if self.state is not PowerState.FAULT:
            self.state, self.fault_code = PowerState.FAULT, code

    def command(self, controlword: int) -> PowerState:
        """Apply one controlword (sent at each SYNC by the NC); return the new state."""
        rising_reset = controlword & FAULT_RESET_BIT and not (
            self._last_controlword & FAULT_RESET_BIT
        )
        self._last_controlword = controlword
        s = self.state
        if s is PowerState.FAULT:
            if rising_reset:
                self.state, self.fault_code = PowerState.SWITCH_ON_DISABLED, 0
            return self.state
        voltage, quick_stop_off = controlword & 0x02, controlword & 0x04
        switch_on, operation = controlword & 0x01, controlword & 0x08
        if not voltage:
            self.state = PowerState.SWITCH_ON_DISABLED
        elif not quick_stop_off:
            self.state = (
                PowerState.QUICK_STOP_ACTIVE
                if s in (PowerState.OPERATION_ENABLED, PowerState.QUICK_STOP_ACTIVE)
                else PowerState.SWITCH_ON_DISABLED
            )
        elif not switch_on:  # shutdown
            if s is not PowerState.QUICK_STOP_ACTIVE:
                self.state = PowerState.READY_TO_SWITCH_ON
        elif not operation:  # switch on, or disable operation
            if s in (
                PowerState.READY_TO_SWITCH_ON,
                PowerState.OPERATION_ENABLED,
                PowerState.SWITCHED_ON,
            ):
                self.state = PowerState.SWITCHED_ON
        elif s in (PowerState.SWITCHED_ON, PowerState.OPERATION_ENABLED):  # enable operation
            self.state = PowerState.OPERATION_ENABLED
        return self.state


def state_of(statusword: int) -> PowerState | None:
    """The state a statusword shows (its low state bits), None if none matches."""
    for state in PowerState:
        mask = 0x004F if state in (PowerState.SWITCH_ON_DISABLED, PowerState.FAULT) else 0x006F
        if statusword & mask == state.value & mask:
            return state
    return None
