"""The CAN path of the simulated closed loop: a FeedforwardLink over a CAN bus.

Each :meth:`CanFeedforwardLink.transfer` runs one control cycle: the streamer
encodes and sends the feedforward (through the fault injector, if faults are
given), then the drive emulator drains the bus and runs its drive cycle. The
returned current is what the drive applies this cycle, quantised by the frame.
Entering the link connects first (the drive grants the session, a few cycles
without current), as a compensator does before the machine moves.

Example
-------
>>> with CanFeedforwardLink(profile="e2e") as link:
...     applied_A = [link.transfer(k, 0.1) for k in range(3)]
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

from firmware_bridge.faults import Fault
from firmware_bridge.session import Rig
from firmware_bridge.settings import CanConfig, ProfileName

_instances = itertools.count()


class CanFeedforwardLink:
    """Implements ``sim.link.FeedforwardLink``; a context manager owning its buses.

    Parameters
    ----------
    cfg
        The ``[can]`` section (default: its defaults, virtual interface).
    profile
        Overrides ``cfg.profile``.
    faults, seed
        Optional fault injection (see :mod:`firmware_bridge.faults`).
    servo_period_s
        Period of the ``transfer`` calls, if the servo loop runs faster than
        the CAN cycle: a frame then goes every ``cycle_period_s / servo_period_s``
        calls and the drive holds the applied value in between. By default
        every call is one CAN cycle.

    The channel gets a per-instance suffix so that links running side by side
    (tests, parallel simulations) do not hear each other.
    """

    def __init__(
        self,
        cfg: CanConfig | None = None,
        *,
        profile: ProfileName | None = None,
        faults: Sequence[Fault] = (),
        seed: int = 0,
        servo_period_s: float | None = None,
    ) -> None:
        cfg = cfg if cfg is not None else CanConfig()
        self.cfg = replace(
            cfg,
            profile=profile or cfg.profile,
            channel=f"{cfg.channel}-link{next(_instances)}",
        )
        self.faults = tuple(faults)
        self.seed = seed
        self._rig: Rig | None = None
        period = servo_period_s if servo_period_s is not None else self.cfg.cycle_period_s
        self.calls_per_frame = max(1, round(self.cfg.cycle_period_s / period))
        self._applied_A = 0.0
        self._first_cycle = 0

    def __enter__(self) -> CanFeedforwardLink:
        self._rig = Rig(self.cfg, self.faults, self.seed)
        try:
            self._first_cycle = self._rig.connect()  # before the motion, as on a machine
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Close the rig and its buses."""
        if self._rig is not None:
            self._rig.close()
            self._rig = None

    @property
    def rig(self) -> Rig:
        """The open rig (only inside the ``with`` block)."""
        if self._rig is None:
            raise RuntimeError("CanFeedforwardLink is used outside its 'with' block")
        return self._rig

    def transfer(self, cycle: int, current_A: float) -> float:
        """Send ``current_A`` in servo cycle ``cycle``; the feedforward the drive applies now."""
        if cycle % self.calls_per_frame == 0:
            can_cycle = self._first_cycle + cycle // self.calls_per_frame
            self._applied_A = self.rig.step(can_cycle, current_A)
        return self._applied_A

    def report(self) -> dict[str, Any]:
        """The stream report of the rig so far."""
        return self.rig.report()
