"""How a feedforward current reaches the drive: the interface and the direct path.

The closed loop hands the compensator's current to a :class:`FeedforwardLink`
once per servo cycle and applies what comes back. The direct path is the
identity with a transport delay in whole servo cycles; the CAN path
(``firmware_bridge.link.CanFeedforwardLink``) implements the same protocol over
a (virtual) bus and a drive emulator.
"""

from __future__ import annotations

from typing import Protocol

import numba
import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.errors import ScenarioError


class FeedforwardLink(Protocol):
    """Carries one feedforward current per servo cycle to the drive."""

    def transfer(self, cycle: int, current_A: float) -> float:
        """Send ``current_A`` in ``cycle``; return the current the drive applies now."""
        ...


@numba.njit(cache=True)
def delayed_hold(
    buffer: FloatArray, delay_cycles: int, hold_cycles: int, cycle: int, current_A: float
) -> float:  # pragma: no cover
    """The direct path's update: ``buffer = [held value, ring of delay + 1 slots]``.

    Cycles must come in order from 0: slot ``cycle % (delay + 1)`` written now is
    read back ``delay`` cycles later, before it is overwritten.
    """
    if cycle % hold_cycles == 0:
        buffer[0] = current_A
    ring = buffer.size - 1
    buffer[1 + cycle % ring] = buffer[0]
    return buffer[1 + (cycle - delay_cycles) % ring] if cycle >= delay_cycles else 0.0


class DirectLink:
    """The identity, delayed by ``delay_cycles`` servo cycles (0 A until then).

    With ``hold_cycles`` > 1 the value is sampled every ``hold_cycles`` cycles
    (those with ``cycle % hold_cycles == 0``) and held in between, as a drive
    holds the value of a field-bus frame that comes slower than the servo loop;
    the delay applies after the hold. Cycles must be numbered from 0 in order.
    The compiled closed loop runs :func:`delayed_hold` on :attr:`buffer` itself.

    Examples
    --------
    >>> link = DirectLink(delay_cycles=1)
    >>> [link.transfer(k, i) for k, i in enumerate([1.0, 2.0, 3.0])]
    [0.0, 1.0, 2.0]
    >>> link = DirectLink(hold_cycles=2)
    >>> [link.transfer(k, i) for k, i in enumerate([1.0, 2.0, 3.0, 4.0])]
    [1.0, 1.0, 3.0, 3.0]
    """

    def __init__(self, delay_cycles: int = 0, hold_cycles: int = 1) -> None:
        if delay_cycles < 0:
            raise ScenarioError(f"transport delay must be >= 0 cycles, got {delay_cycles}")
        if hold_cycles < 1:
            raise ScenarioError(f"hold must be >= 1 cycle, got {hold_cycles}")
        self.delay_cycles = delay_cycles
        self.hold_cycles = hold_cycles
        self.buffer = np.zeros(delay_cycles + 2)

    def transfer(self, cycle: int, current_A: float) -> float:
        """Sample ``current_A`` (on a hold boundary) and return the held value of
        ``delay_cycles`` ago."""
        return float(
            delayed_hold(self.buffer, self.delay_cycles, self.hold_cycles, cycle, current_A)
        )
