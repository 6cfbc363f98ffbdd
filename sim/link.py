"""How a feedforward current reaches the drive: the interface and the direct path.

The closed loop hands the compensator's current to a :class:`FeedforwardLink`
once per servo cycle and applies what comes back. The direct path is the
identity with a transport delay in whole servo cycles; the CAN path
(``firmware_bridge.link.CanFeedforwardLink``) implements the same protocol over
a (virtual) bus and a drive emulator.
"""

from __future__ import annotations

from collections import deque
from typing import Protocol

from gms_comp.errors import ScenarioError


class FeedforwardLink(Protocol):
    """Carries one feedforward current per servo cycle to the drive."""

    def transfer(self, cycle: int, current_A: float) -> float:
        """Send ``current_A`` in ``cycle``; return the current the drive applies now."""
        ...


class DirectLink:
    """The identity, delayed by ``delay_cycles`` servo cycles (0 A until then).

    Examples
    --------
    >>> link = DirectLink(delay_cycles=1)
    >>> [link.transfer(k, i) for k, i in enumerate([1.0, 2.0, 3.0])]
    [0.0, 1.0, 2.0]
    """

    def __init__(self, delay_cycles: int = 0) -> None:
        if delay_cycles < 0:
            raise ScenarioError(f"transport delay must be >= 0 cycles, got {delay_cycles}")
        self._queue: deque[float] = deque([0.0] * delay_cycles)

    def transfer(self, cycle: int, current_A: float) -> float:
        """Queue ``current_A`` and return the one sent ``delay_cycles`` ago."""
        self._queue.append(current_A)
        return self._queue.popleft()
