"""The emulated CiA 402 drive: a canopen LocalNode (SDO, EMCY) around the cia402 receiver."""

from __future__ import annotations

import can
import canopen

from firmware_bridge.profiles.cia402.codec import Cia402Codec, configure_drive, load_drive_od
from firmware_bridge.profiles.cia402.receiver import Cia402Receiver
from firmware_bridge.settings import CanConfig
from firmware_bridge.supervisor import RejectCounts


class Cia402Drive:
    """The drive side of cia402 on ``bus`` (implements ``DriveSide``).

    Parameters
    ----------
    cfg
        The ``[can]`` section; its supervision times are written into the
        object dictionary as an NC would by SDO at start-up.
    bus
        The drive's bus handle.
    """

    def __init__(self, cfg: CanConfig, bus: can.BusABC) -> None:
        od = load_drive_od(cfg.drive_node_id)
        self.node = canopen.LocalNode(cfg.drive_node_id, od)
        network = canopen.Network(bus)  # no notifier: the emulator dispatches itself
        network.add_node(self.node)
        configure_drive(self.node, cfg)
        self.codec = Cia402Codec(cfg, od)
        limit = min(self.codec.limit_raw, self.codec.to_raw(cfg.max_current_A))
        self.receiver = Cia402Receiver(self.node, self.codec, cfg, limit)

    @property
    def counts(self) -> RejectCounts:
        """Received RPDOs by verdict."""
        return self.receiver.counts

    def handle(self, msg: can.Message, now_s: float) -> None:
        """Take one frame (RPDO, SYNC, heartbeat, SDO, NMT)."""
        self.receiver.on_message(msg, now_s)

    def set_real_time(self, real_time: bool) -> None:
        """Run on the drive's own clock (True) or stepped (False)."""
        self.receiver.set_real_time(real_time)

    def tick(self, now_s: float, cycle: int) -> tuple[int, bytes | None]:
        """One drive cycle; the applied 0x60B2 value and the RPDO applied fresh in it."""
        out = self.receiver.tick(now_s)
        return out, self.receiver.applied_data

    def from_raw(self, raw: int) -> float:
        """Per mille of the rated current -> A."""
        return self.codec.from_raw(raw)

    def state(self) -> str:
        """The receiver's state (operation_enabled, waiting, or the 0x6007 reaction)."""
        return self.receiver.state

    def emcy(self) -> list[str]:
        """EMCY codes sent, as ``0xNNNN``."""
        return [f"0x{code:04X}" for code in self.receiver.emcy_sent]
