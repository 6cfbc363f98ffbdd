"""Profile ``cia402``: a CiA 402 drive, feedforward in the torque offset 0x60B2.

The drive's EDS (``cia402_drive.eds``, shipped in the package) is the source of
the COB-IDs, the PDO mappings and the supervision times; :class:`Cia402Codec`
checks that it maps what this module packs. 0x60B2 is INTEGER16 in per mille of
the rated torque 0x6076 (rated force for a linear motor); since the force is the
force constant times the current, that is per mille of the rated current 0x6075,
which is how the compensator scales its current.

PDOs, all of transmission type 1 (at every SYNC):

- RPDO1, from the NC: controlword 0x6040, target position 0x607A (increments);
- RPDO2, from the compensator: torque offset 0x60B2, the drive cycle it is meant for
  (0x2001), the compensator's session (0x2003) and the frame's mode (0x2004), by which
  the drive dates and claims each frame (:mod:`firmware_bridge.freshness`);
- TPDO1, from the drive: statusword 0x6041, the last tick it ran (0x2002), the session
  it holds (0x2005), current actual 0x6078 (per mille of 0x6075), the counter of the
  SYNC it answers (0x2006: a recorder files the sample under its SYNC, however late);
- TPDO2, from the drive: position actual 0x6064 and velocity actual 0x606C
  (increments of 0x2010 pm, increments per second).

The drive takes the RPDO2s received since the last SYNC and, at that SYNC, applies
the newest one that is fresh, rejecting older, repeated, stale and foreign ones.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can
import canopen
from canopen.objectdictionary import ObjectDictionary

from firmware_bridge.freshness import STAMP_MODULUS, Command, Mode
from firmware_bridge.resources import packaged_path
from firmware_bridge.settings import CanConfig
from gms_comp.errors import BusError

CONTROLWORD, STATUSWORD = 0x6040, 0x6041
TARGET_POSITION, POSITION_ACTUAL, VELOCITY_ACTUAL = 0x607A, 0x6064, 0x606C
CURRENT_ACTUAL, RATED_CURRENT = 0x6078, 0x6075
TORQUE_OFFSET = 0x60B2
FF_CYCLE, DRIVE_CYCLE, FF_SESSION, FF_MODE, SESSION_HELD = 0x2001, 0x2002, 0x2003, 0x2004, 0x2005
SYNC_ANSWERED = 0x2006
POSITION_UNIT_PM, FORCE_CONSTANT_MN_PER_A = 0x2010, 0x2011
PRODUCER_HEARTBEAT = 0x1017
ABORT_CONNECTION_OPTION = 0x6007
HEARTBEAT_OPERATIONAL = 0x05
PER_MILLE = 1000


@dataclass(frozen=True)
class PdoLayout:
    """One PDO: its communication and mapping objects, the objects it maps, its packing."""

    comm: int
    mapping: int
    objects: tuple[tuple[int, int], ...]  # (index, bits) in order
    packing: struct.Struct

    @property
    def size(self) -> int:
        """Payload bytes."""
        return self.packing.size


NC_RPDO = PdoLayout(
    0x1400, 0x1600, ((CONTROLWORD, 16), (TARGET_POSITION, 32)), struct.Struct("<Hi")
)
FF_RPDO = PdoLayout(
    0x1401,
    0x1601,
    ((TORQUE_OFFSET, 16), (FF_CYCLE, 16), (FF_SESSION, 8), (FF_MODE, 8)),
    struct.Struct("<hHBB"),
)
STATUS_TPDO = PdoLayout(
    0x1800,
    0x1A00,
    (
        (STATUSWORD, 16),
        (DRIVE_CYCLE, 16),
        (SESSION_HELD, 8),
        (CURRENT_ACTUAL, 16),
        (SYNC_ANSWERED, 8),
    ),
    struct.Struct("<HHBhB"),
)
MOTION_TPDO = PdoLayout(
    0x1801, 0x1A01, ((POSITION_ACTUAL, 32), (VELOCITY_ACTUAL, 32)), struct.Struct("<ii")
)
PDOS = (NC_RPDO, FF_RPDO, STATUS_TPDO, MOTION_TPDO)

# NMT commands and heartbeat states (CiA 301)
NMT_START, NMT_STOP, NMT_ENTER_PRE_OPERATIONAL = 0x01, 0x02, 0x80
HEARTBEAT_PRE_OPERATIONAL = 0x7F
# EMCY error codes (CiA 301 communication errors)
EMCY_RPDO_TIMEOUT = 0x8250
EMCY_HEARTBEAT = 0x8130
EMCY_SYNC_LOST = 0x8100
ABORT_ACTIONS = {0: "no_action", 1: "fault", 2: "disable_voltage", 3: "quick_stop"}


@dataclass(frozen=True)
class DriveReport:
    """TPDO1 of the drive, decoded."""

    statusword: int
    cycle: int
    session: int
    current_raw: int
    sync_counter: int  # the counter byte of the SYNC it answers (0: the SYNC had none)


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
    """Frames of the drive's PDOs, laid out as its EDS says (checked against :data:`PDOS`)."""

    def __init__(self, cfg: CanConfig, od: ObjectDictionary) -> None:
        for pdo in PDOS:
            _check_layout(od, pdo)
        self.cob_ids = {pdo: od_default(od, pdo.comm, 1) & 0x7FF for pdo in PDOS}
        self.rpdo_cob_id = self.cob_ids[FF_RPDO]
        self.nc_cob_id = self.cob_ids[NC_RPDO]
        self.status_cob_id = self.cob_ids[STATUS_TPDO]
        self.motion_cob_id = self.cob_ids[MOTION_TPDO]
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

    def rpdo_frame(self, raw: int, cycle: int, session: int, mode: Mode) -> can.Message:
        """RPDO2: torque offset ``raw`` (per mille) for drive cycle ``cycle``."""
        data = FF_RPDO.packing.pack(raw, cycle % STAMP_MODULUS, session, int(mode))
        return can.Message(arbitration_id=self.rpdo_cob_id, data=data, is_extended_id=False)

    @staticmethod
    def unpack_rpdo(data: bytes) -> Command | None:
        """The fields of an RPDO2 payload; None if its length or a field is out of range."""
        if len(data) != FF_RPDO.size:
            return None
        raw, cycle, session, mode = FF_RPDO.packing.unpack(data)
        if session == 0 or mode not in tuple(Mode):
            return None
        return Command(int(cycle), int(raw), int(session), Mode(mode))

    def status_frame(
        self, statusword: int, cycle: int, session: int, current_raw: int, sync_counter: int = 0
    ) -> can.Message:
        """TPDO1 of the drive."""
        data = STATUS_TPDO.packing.pack(
            statusword, cycle % STAMP_MODULUS, session, current_raw, sync_counter
        )
        return can.Message(arbitration_id=self.status_cob_id, data=data, is_extended_id=False)

    @staticmethod
    def unpack_status(data: bytes) -> DriveReport | None:
        """TPDO1's fields, None if its length is wrong."""
        if len(data) != STATUS_TPDO.size:
            return None
        return DriveReport(*(int(v) for v in STATUS_TPDO.packing.unpack(data)))

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


def _check_layout(od: ObjectDictionary, pdo: PdoLayout) -> None:
    count = od_default(od, pdo.mapping, 0)
    mapping = [od_default(od, pdo.mapping, sub) for sub in range(1, count + 1)]
    wanted = [(index << 16) | bits for index, bits in pdo.objects]
    if mapping != wanted:
        raise BusError(
            f"PDO mapping 0x{pdo.mapping:04X} must map "
            + ", ".join(f"0x{m:08X}" for m in wanted)
            + "; the EDS maps "
            + (", ".join(f"0x{m:08X}" for m in mapping) or "nothing")
        )
    if od_default(od, pdo.comm, 2) != 1:
        raise BusError(f"PDO 0x{pdo.comm:04X} must have transmission type 1 (every SYNC)")


def heartbeat_frame(cob_id: int) -> can.Message:
    """An NMT heartbeat saying "operational"."""
    return can.Message(
        arbitration_id=cob_id, data=bytes([HEARTBEAT_OPERATIONAL]), is_extended_id=False
    )


def configure_drive(node: canopen.LocalNode, cfg: CanConfig) -> None:
    """Write the supervision times of ``cfg`` into the drive's object dictionary,
    as an NC would by SDO at start-up."""
    write_object(node, 0x1006, None, round(cfg.cycle_period_s * 1e6))
    write_object(node, FF_RPDO.comm, 5, max(1, round(cfg.rx_timeout_s * 1e3)))
    consumer_ms = max(1, round(1.5 * cfg.heartbeat_period_s * 1e3))
    write_object(node, 0x1016, 1, (cfg.compensator_node_id << 16) | consumer_ms)
    write_object(node, PRODUCER_HEARTBEAT, None, max(1, round(cfg.heartbeat_period_s * 1e3)))
    write_object(node, 0x6075, None, round(cfg.rated_current_A * 1e3))
