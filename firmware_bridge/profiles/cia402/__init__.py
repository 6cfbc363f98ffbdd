"""Profile ``cia402``: a standard servo drive, feedforward in the torque offset 0x60B2.

Codec and object dictionary in :mod:`.codec` (the drive's EDS is the source),
the compensator's side in :mod:`.tx`, the drive's in :mod:`.receiver` and
:mod:`.drive`, the NC's SYNC in :mod:`.nc`. ``[can]`` keys of its own:
``sync_master``, ``heartbeat_period_s``, ``drive_node_id``,
``compensator_node_id``, ``rated_current_A``.
"""

from __future__ import annotations

import can

from firmware_bridge.profiles.base import Profile
from firmware_bridge.profiles.cia402.drive import Cia402Drive
from firmware_bridge.profiles.cia402.nc import SyncProducer
from firmware_bridge.profiles.cia402.tx import Cia402Tx
from firmware_bridge.settings import CanConfig


class Cia402Profile:
    """The cia402 profile (implements ``firmware_bridge.profiles.base.Profile``)."""

    name = "cia402"

    def make_tx(self, cfg: CanConfig) -> Cia402Tx:
        """The compensator's sending side."""
        return Cia402Tx(cfg)

    def make_drive(self, cfg: CanConfig, bus: can.BusABC) -> Cia402Drive:
        """The emulated drive on ``bus``."""
        return Cia402Drive(cfg, bus)

    def make_nc(self, cfg: CanConfig, bus: can.BusABC) -> SyncProducer | None:
        """The NC's SYNC producer when the compensator follows SYNC."""
        if cfg.sync_master:
            return None
        return SyncProducer(bus, Cia402Tx(cfg).codec, cfg.cycle_period_s)


PROFILE: Profile = Cia402Profile()
