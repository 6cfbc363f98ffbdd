"""Profile ``cia402``: a standard servo drive, feedforward in the torque offset 0x60B2.

The drive's EDS (``cia402_drive.eds``, shipped in the package) is the source of
the COB-IDs, the RPDO mapping and the supervision times. 0x60B2 is INTEGER16 in
per mille of the rated torque 0x6076 (rated force for a linear motor); since the
force is the force constant times the current, that is per mille of the rated
current 0x6075, which is how the compensator scales its current.

RPDO1 maps 0x60B2 and, in its third byte, the alive counter 0x2001 (the
compensator's cycle index modulo 256), by which the drive dates each frame (see
:mod:`firmware_bridge.freshness`): a counter-less PDO cannot tell a frame held
up somewhere from a fresh one. RPDO1 has transmission type 1: the drive takes
the RPDOs received since the last SYNC and, at that SYNC, applies the newest
one that is fresh, rejecting older, repeated and stale ones.
"""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any

import can
import canopen
from canopen.objectdictionary import ObjectDictionary

from firmware_bridge.freshness import COUNTER_MODULUS
from firmware_bridge.resources import packaged_path
from firmware_bridge.settings import CanConfig
from gms_comp.errors import BusError

TORQUE_OFFSET = 0x60B2
ALIVE_COUNTER = 0x2001  # manufacturer object mapped beside 0x60B2
PRODUCER_HEARTBEAT = 0x1017
RPDO1_COMM, RPDO1_MAP = 0x1400, 0x1600
ABORT_CONNECTION_OPTION = 0x6007
RPDO_LAYOUT = struct.Struct("<hB")  # 0x60B2 INTEGER16, 0x2001 UNSIGNED8
HEARTBEAT_OPERATIONAL = 0x05
PER_MILLE = 1000

# EMCY error codes (CiA 301 communication errors)
NMT_START, NMT_STOP, NMT_ENTER_PRE_OPERATIONAL = 0x01, 0x02, 0x80
HEARTBEAT_PRE_OPERATIONAL = 0x7F
EMCY_RPDO_TIMEOUT = 0x8250
EMCY_HEARTBEAT = 0x8130
EMCY_SYNC_LOST = 0x8100
ABORT_ACTIONS = {0: "no_action", 1: "fault", 2: "disable_voltage", 3: "quick_stop"}


def default_eds_path() -> Path:
    """Path of the packaged drive EDS."""
    return packaged_path("cia402_drive.eds")


def load_drive_od(node_id: int, eds_path: str | Path | None = None) -> ObjectDictionary:
    """The drive's object dictionary for node ``node_id`` from the EDS."""
    path = Path(eds_path) if eds_path is not None else default_eds_path()
    try:
        return canopen.import_od(str(path), node_id)
    except (OSError, KeyError, ValueError) as err:
        raise BusError(f"{path}: not a usable drive EDS ({err})") from err


def od_default(od: ObjectDictionary, index: int, subindex: int | None = None) -> int:
    """Default value of an object of the EDS."""
    entry: Any = od[index] if subindex is None else od[index][subindex]  # type: ignore[index]
    return int(entry.default)


def read_object(node: canopen.LocalNode, index: int, subindex: int | None = None) -> int:
    """Value of an object of the local node's dictionary."""
    return int(_sdo_entry(node, index, subindex).raw)


def write_object(node: canopen.LocalNode, index: int, subindex: int | None, value: int) -> None:
    """Write an object of the local node's dictionary."""
    _sdo_entry(node, index, subindex).raw = value


def _sdo_entry(node: canopen.LocalNode, index: int, subindex: int | None) -> Any:
    entry: Any = node.sdo[index]
    return entry if subindex is None else entry[subindex]


class Cia402Codec:
    """Frames of the compensator side, laid out as the drive's EDS says."""

    def __init__(self, cfg: CanConfig, od: ObjectDictionary) -> None:
        mapping = [
            od_default(od, RPDO1_MAP, sub) for sub in range(1, od_default(od, RPDO1_MAP, 0) + 1)
        ]
        wanted = [(TORQUE_OFFSET << 16) | 0x10, (ALIVE_COUNTER << 16) | 0x08]
        if mapping != wanted:
            found = ", ".join(f"0x{m:08X}" for m in mapping)
            raise BusError(
                "RPDO1 must map 0x60B2 (16 bit) then the alive counter 0x2001 (8 bit), "
                f"the EDS maps {found}"
            )
        if od_default(od, RPDO1_COMM, 2) != 1:
            raise BusError("RPDO1 must have transmission type 1 (synchronous, every SYNC)")
        self.rpdo_cob_id = od_default(od, RPDO1_COMM, 1) & 0x7FF
        self.sync_cob_id = od_default(od, 0x1005) & 0x7FF
        self.heartbeat_cob_id = 0x700 + cfg.compensator_node_id
        self.drive_node_id = cfg.drive_node_id
        self.rated_current_A = cfg.rated_current_A
        self.limit_raw = 2**15 - 1

    def to_raw(self, current_A: float) -> int:
        """Current in A -> per mille of the rated current (not saturated)."""
        return round(PER_MILLE * current_A / self.rated_current_A)

    def from_raw(self, raw: int) -> float:
        """Per mille of the rated current -> current in A."""
        return raw * self.rated_current_A / PER_MILLE

    def rpdo_frame(self, raw: int, counter: int) -> can.Message:
        """RPDO1 with torque offset ``raw`` (per mille) and the cycle's alive counter."""
        return can.Message(
            arbitration_id=self.rpdo_cob_id,
            data=RPDO_LAYOUT.pack(raw, counter % COUNTER_MODULUS),
            is_extended_id=False,
        )

    @staticmethod
    def unpack_rpdo(data: bytes) -> tuple[int, int] | None:
        """``(torque offset, counter)`` of an RPDO1 payload, None if its length is wrong."""
        if len(data) != RPDO_LAYOUT.size:
            return None
        raw, counter = RPDO_LAYOUT.unpack(data)
        return int(raw), int(counter)

    def sync_frame(self, counter: int | None = None) -> can.Message:
        """A SYNC frame, with the CiA 301 SYNC counter byte if ``counter`` is given."""
        data = b"" if counter is None else bytes([counter])
        return can.Message(arbitration_id=self.sync_cob_id, data=data, is_extended_id=False)

    def leave_operation_frame(self) -> can.Message:
        """NMT "enter pre-operational" to the drive: PDOs and their supervision end."""
        return can.Message(
            arbitration_id=0x000,
            data=bytes([NMT_ENTER_PRE_OPERATIONAL, self.drive_node_id]),
            is_extended_id=False,
        )

    def heartbeat_frame(self) -> can.Message:
        """The compensator's heartbeat, operational."""
        return heartbeat_frame(self.heartbeat_cob_id)


def heartbeat_frame(cob_id: int) -> can.Message:
    """An NMT heartbeat saying "operational"."""
    return can.Message(
        arbitration_id=cob_id, data=bytes([HEARTBEAT_OPERATIONAL]), is_extended_id=False
    )


def configure_drive(node: canopen.LocalNode, cfg: CanConfig) -> None:
    """Write the supervision times of ``cfg`` into the drive's object dictionary,
    as an NC would by SDO at start-up."""
    write_object(node, 0x1006, None, round(cfg.cycle_period_s * 1e6))
    write_object(node, RPDO1_COMM, 5, max(1, round(cfg.rx_timeout_s * 1e3)))
    consumer_ms = max(1, round(1.5 * cfg.heartbeat_period_s * 1e3))
    write_object(node, 0x1016, 1, (cfg.compensator_node_id << 16) | consumer_ms)
    write_object(node, PRODUCER_HEARTBEAT, None, max(1, round(cfg.heartbeat_period_s * 1e3)))
    write_object(node, 0x6075, None, round(cfg.rated_current_A * 1e3))
