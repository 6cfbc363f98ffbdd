"""Profile ``e2e``: custom drive firmware, frames defined in ``gms_ff.dbc``.

The DBC is the single source of truth for the layout, the scaling and the
E2E data IDs (message attribute ``E2EDataId``). Frames follow the AUTOSAR E2E
profile 5 layout: CRC-16 in bytes 0..1 over bytes 2..7 and the data ID, an
8-bit alive counter in byte 2. cantools encodes (``strict=True``, after the
caller has saturated) and decodes; the CRC equals :mod:`cantools.autosar`'s.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can
import cantools
from cantools.database.can import Message

from firmware_bridge.freshness import COUNTER_MODULUS
from firmware_bridge.resources import packaged_path
from gms_comp.errors import BusError

CRC_BYTES = 2


def _crc16_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else crc << 1
        table.append(crc & 0xFFFF)
    return tuple(table)


_CRC16_TABLE = _crc16_table()


def profile5_crc(data: bytes, data_id: int) -> int:
    """CRC-16/CCITT-FALSE over ``data[2:]`` and the data ID (low, high byte).

    The same value as ``cantools.autosar.compute_profile5_crc`` (the tests check
    it), table-driven because it runs in the 1 kHz control loop.
    """
    crc = 0xFFFF
    for byte in (*data[CRC_BYTES:], data_id & 0xFF, data_id >> 8):
        crc = ((crc << 8) & 0xFFFF) ^ _CRC16_TABLE[(crc >> 8) ^ byte]
    return crc


def _with_crc(data: bytes, data_id: int) -> bytes:
    return profile5_crc(data, data_id).to_bytes(CRC_BYTES, "little") + data[CRC_BYTES:]


def _crc_holds(data: bytes, data_id: int) -> bool:
    return int.from_bytes(data[:CRC_BYTES], "little") == profile5_crc(data, data_id)


def default_dbc_path() -> Path:
    """Path of the packaged feedforward DBC."""
    return packaged_path("gms_ff.dbc")


@dataclass(frozen=True)
class DriveStatus:
    """The drive's status frame, decoded."""

    counter: int
    applied_current_A: float
    state: int
    rejected: int


class E2eCodec:
    """Encode and check the feedforward and status frames of the DBC."""

    def __init__(self, dbc_path: str | Path | None = None) -> None:
        path = Path(dbc_path) if dbc_path is not None else default_dbc_path()
        try:
            db = cantools.database.load_file(str(path), strict=True)
            if not isinstance(db, cantools.database.can.Database):
                raise cantools.database.Error("not a CAN database")
            self.command = db.get_message_by_name("FfCommand")
            self.status = db.get_message_by_name("DriveStatus")
            current = self.command.get_signal_by_name("Current")
            self.command_data_id = _data_id(self.command)
            self.status_data_id = _data_id(self.status)
        except (OSError, KeyError, cantools.database.Error) as err:
            raise BusError(f"{path}: not a usable feedforward DBC ({err})") from err
        self.dbc_path = path
        if current.minimum is None or current.maximum is None:
            raise BusError(f"{path}: signal FfCommand.Current needs a minimum and a maximum")
        self.scale_A = float(current.scale)
        self.raw_range = (
            round(current.minimum / self.scale_A),
            round(current.maximum / self.scale_A),
        )
        self.limit_raw = min(-self.raw_range[0], self.raw_range[1])

    def to_raw(self, current_A: float) -> int:
        """Current in A -> the ``Current`` signal's raw value (not saturated)."""
        return round(current_A / self.scale_A)

    def from_raw(self, raw: int) -> float:
        """The ``Current`` signal's raw value -> current in A."""
        return raw * self.scale_A

    def encode_command(self, counter: int, raw: int) -> bytes:
        """FfCommand payload with ``counter`` (modulo 256), ``raw`` and its CRC."""
        data = self.command.encode(
            {"Crc": 0, "Counter": counter % COUNTER_MODULUS, "Current": raw},
            scaling=False,
            strict=True,
        )
        return _with_crc(data, self.command_data_id)

    def command_frame(self, counter: int, raw: int) -> can.Message:
        """FfCommand frame with ``counter`` and ``raw``."""
        return can.Message(
            arbitration_id=self.command.frame_id,
            data=self.encode_command(counter, raw),
            is_extended_id=False,
        )

    def check_command(self, data: bytes) -> tuple[int, int] | None:
        """``(counter, raw current)`` of an intact, in-range command frame, else None."""
        if len(data) != self.command.length or not _crc_holds(data, self.command_data_id):
            return None
        fields = _decode_raw(self.command, data)
        low, high = self.raw_range
        if not low <= fields["Current"] <= high:  # decoding does no range check
            return None
        return fields["Counter"], fields["Current"]

    def status_frame(
        self, counter: int, applied_raw: int, state: int, rejected: int
    ) -> can.Message:
        """DriveStatus frame of the drive's cycle ``counter``."""
        data = self.status.encode(
            {
                "Crc": 0,
                "Counter": counter % COUNTER_MODULUS,
                "AppliedCurrent": applied_raw,
                "State": state,
                "Rejected": rejected % 256,
            },
            scaling=False,
            strict=True,
        )
        return can.Message(
            arbitration_id=self.status.frame_id,
            data=_with_crc(data, self.status_data_id),
            is_extended_id=False,
        )

    def check_status(self, data: bytes) -> DriveStatus | None:
        """The decoded status of an intact DriveStatus payload, else None."""
        if len(data) != self.status.length or not _crc_holds(data, self.status_data_id):
            return None
        f = _decode_raw(self.status, data)
        return DriveStatus(
            f["Counter"], self.from_raw(f["AppliedCurrent"]), f["State"], f["Rejected"]
        )


def _data_id(message: Message) -> int:
    attributes: Any = message.dbc.attributes if message.dbc is not None else {}
    return int(attributes["E2EDataId"].value)


def _decode_raw(message: Message, data: bytes) -> dict[str, int]:
    fields: Any = message.decode(data, scaling=False, decode_choices=False)
    return {name: int(value) for name, value in fields.items()}
