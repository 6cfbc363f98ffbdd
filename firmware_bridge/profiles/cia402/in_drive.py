"""The GMS observer inside the drive: the table downloaded by SDO, run at the servo rate.

At commissioning the compensator downloads a table into the drive (the gms-comp table
file, JSON, into the DOMAIN object 0x2100 by SDO segmented or block transfer, after its
CRC-32 into 0x2101); the drive checks the CRC, that the table is one and that it fits
(at most :data:`MAX_ELEMENTS` elements, :data:`MAX_TABLE_BYTES`), and refuses it with an
SDO abort otherwise; 0x2102 then shows the elements loaded. From then on the compensator
sends only the friction level (RPDO2 in mode ``in_drive``, per mille in 0x60B2): the drive
steps its own observer every servo cycle on its position command (the target
interpolated over the bus cycle) and its speed, as the compensator follows the NC's
target (on the encoder, a reversal transient's extension turned with the axis's ringing
after each reversal, tens of nm, and made the peak worse than no feedforward), and
adds ``level * F / k_f`` to its current command (:class:`InDriveObserver`). The level goes
through the drive's supervision like any command: a lost link ramps it, and with it the
feedforward, to zero.
"""

from __future__ import annotations

import zlib
from typing import Any

from canopen.sdo.exceptions import SdoAbortedError

from firmware_bridge.profiles.cia402.codec import PER_MILLE
from gms_comp.errors import GmsCompError
from gms_comp.runtime.observer import CompensatorConfig, FrictionObserver
from gms_comp.tables.table import GmsTable, table_from_dict
from gms_comp.validation import decode_utf8, parse_json

TABLE_OBJECT, TABLE_CRC, TABLE_LOADED = 0x2100, 0x2101, 0x2102
MAX_TABLE_BYTES = 256 * 1024
MAX_ELEMENTS = 64
ABORT_NO_MEMORY = 0x05040005  # CiA 301: out of memory (the table does not fit)
ABORT_NOT_STORED = 0x08000020  # data cannot be transferred or stored (CRC, not a table)


def table_crc(data: bytes) -> int:
    """The CRC-32 a table download is checked by (zlib's, of the bytes as sent)."""
    return zlib.crc32(data) & 0xFFFFFFFF


class InDriveObserver:
    """The drive's own observer of a downloaded table, at the servo rate.

    Parameters
    ----------
    table
        The downloaded table (its forces the whole axis's).
    force_constant_N_per_A
        The drive's motor constant.
    servo_period_s
        The drive's servo (current-loop command) period.
    """

    def __init__(
        self, table: GmsTable, force_constant_N_per_A: float, servo_period_s: float
    ) -> None:
        self.elements = table.n_elements
        self.observer = FrictionObserver(
            table, force_constant_N_per_A, servo_period_s, 1.0, CompensatorConfig()
        )
        self.level = 0.0

    def set_level(self, raw_permille: int) -> None:
        """The level sent by the compensator, per mille (0: no feedforward)."""
        self.level = raw_permille / PER_MILLE

    def __call__(self, position_m: float, velocity_m_s: float) -> float:
        """One servo cycle: the feedforward current in A (the model always steps)."""
        return self.level * self.observer.step(position_m, velocity_m_s)


def accept_table(data: bytes, crc: int, where: str) -> GmsTable:
    """The table of a download, or an SDO abort: CRC, size, a valid table that fits."""
    if len(data) > MAX_TABLE_BYTES:
        raise SdoAbortedError(ABORT_NO_MEMORY)
    if table_crc(data) != crc:
        raise SdoAbortedError(ABORT_NOT_STORED)
    try:
        doc: Any = parse_json(decode_utf8(data, where), where)
        table = table_from_dict(doc, where)
    except GmsCompError:
        raise SdoAbortedError(ABORT_NOT_STORED) from None
    if table.n_elements > MAX_ELEMENTS:
        raise SdoAbortedError(ABORT_NO_MEMORY)
    return table
