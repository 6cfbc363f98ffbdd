"""Profile ``e2e``: custom drive firmware, frames defined in ``gms_ff.dbc``.

Codec and CRC in :mod:`.codec` (the DBC is the source), the compensator's side
in :mod:`.tx`, the drive's in :mod:`.receiver` and :mod:`.drive`; the firmware's
C handler is ``firmware_bridge/c/ff_handler.c``. ``[can]`` keys of its own:
``status_every_cycles``.
"""

from __future__ import annotations

import can

from firmware_bridge.profiles.base import Profile
from firmware_bridge.profiles.e2e.drive import E2eDrive
from firmware_bridge.profiles.e2e.tx import E2eTx
from firmware_bridge.settings import CanConfig


class E2eProfile:
    """The e2e profile (implements ``firmware_bridge.profiles.base.Profile``)."""

    name = "e2e"

    def make_tx(self, cfg: CanConfig) -> E2eTx:
        """The compensator's sending side."""
        return E2eTx(cfg)

    def make_drive(self, cfg: CanConfig, bus: can.BusABC) -> E2eDrive:
        """The emulated drive on ``bus``."""
        return E2eDrive(cfg, bus)

    def make_nc(self, cfg: CanConfig, bus: can.BusABC) -> None:
        """No SYNC in this profile."""
        return None


PROFILE: Profile = E2eProfile()
