"""The emulated CiA 402 drive: a canopen LocalNode (SDO, EMCY) around the cia402 receiver."""

from __future__ import annotations

import can
import canopen

from firmware_bridge.profiles.cia402.codec import Cia402Codec, configure_drive, load_drive_od
from firmware_bridge.profiles.cia402.receiver import Cia402Receiver
from firmware_bridge.settings import CanConfig
from firmware_bridge.supervisor import RejectCounts

STATUSWORD_OPERATION_ENABLED = 0x0237  # ready, switched on, operation enabled, quick stop off
STATUSWORD_SWITCH_ON_DISABLED = 0x0250


class Cia402Drive:
    """The drive side of cia402 on ``bus`` (implements ``DriveSide``).

    Parameters
    ----------
    cfg
        The ``[can]`` section; its supervision times are written into the
        object dictionary as an NC would by SDO at start-up.
    bus
        The drive's bus handle.

    At each SYNC it judges the feedforward RPDOs of the cycle; at the tick after every
    ``status_every_cycles``-th SYNC (TPDO1's transmission type) it sends TPDO1 with the
    tick just run and the session it holds: what the compensator dates its frames by.
    This drive moves nothing: it sends no TPDO2 (motion).
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
        self.status_every = cfg.status_every_cycles
        self._syncs = 0
        self._status_due = False

    @property
    def counts(self) -> RejectCounts:
        """Received RPDOs by verdict."""
        return self.receiver.counts

    def handle(self, msg: can.Message, now_s: float) -> None:
        """Take one frame (RPDO, SYNC, heartbeat, SDO, NMT); at a SYNC, send the TPDOs."""
        if self.receiver.on_message(msg, now_s):
            self._status_due |= self._syncs % self.status_every == 0
            self._syncs += 1

    def _send_status(self) -> None:
        receiver = self.receiver
        enabled = receiver.state == "operation_enabled" or receiver.state == "waiting"
        status = self.codec.status_frame(
            STATUSWORD_OPERATION_ENABLED if enabled else STATUSWORD_SWITCH_ON_DISABLED,
            receiver.last_cycle,
            receiver.clock.session,
            receiver.supervisor.output_raw,
        )
        self.node.network.send_message(status.arbitration_id, bytes(status.data))

    def set_real_time(self, real_time: bool) -> None:
        """Nothing to set: the SYNC count dates every frame, stepped or in real time."""

    def tick(self, now_s: float, cycle: int) -> tuple[int, bytes | None]:
        """One drive cycle; the applied 0x60B2 value and the RPDO applied fresh in it.
        TPDO1 follows when a SYNC asked for it."""
        out = self.receiver.tick(now_s)
        if self._status_due:
            self._status_due = False
            self._send_status()
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
