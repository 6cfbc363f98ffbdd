"""Profile ``e2e``: custom drive firmware, frames defined in ``gms_ff.dbc``.

The DBC is the single source of truth for the layout, the scaling and the
E2E data IDs (message attribute ``E2EDataId``). Frames follow the AUTOSAR E2E
profile 5 style: CRC-16 in bytes 0..1 over bytes 2..7 and the data ID; in place
of the 8-bit alive counter, the 16-bit drive cycle (bytes 2..3) by which the drive
dates the frame (:mod:`firmware_bridge.freshness`), then the session and mode.
cantools encodes (``strict=True``, after the caller has saturated) and decodes; the
CRC equals :mod:`cantools.autosar`'s.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can
import cantools
from cantools.database.can import Message

from firmware_bridge.freshness import STAMP_MODULUS, Command, Mode
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

    cycle: int
    applied_current_A: float
    session: int
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
            self._ranges = {
                name: _raw_range(self.command.get_signal_by_name(name))
                for name in ("Current", "Session", "Mode")
            }
        except (OSError, KeyError, cantools.database.Error) as err:
            raise BusError(f"{path}: not a usable feedforward DBC ({err})") from err
        self.dbc_path = path
        self.scale_A = float(current.scale)
        self.raw_range = self._ranges["Current"]
        self.limit_raw = min(-self.raw_range[0], self.raw_range[1])

    def to_raw(self, current_A: float) -> int:
        """Current in A -> the ``Current`` signal's raw value (not saturated)."""
        return round(current_A / self.scale_A)

    def from_raw(self, raw: int) -> float:
        """The ``Current`` signal's raw value -> current in A."""
        return raw * self.scale_A

    def encode_command(self, cycle: int, raw: int, session: int, mode: Mode) -> bytes:
        """FfCommand payload for drive cycle ``cycle`` (modulo 2**16), with its CRC."""
        data = self.command.encode(
            {
                "Crc": 0,
                "Cycle": cycle % STAMP_MODULUS,
                "Current": raw,
                "Session": session,
                "Mode": int(mode),
            },
            scaling=False,
            strict=True,
        )
        return _with_crc(data, self.command_data_id)

    def command_frame(self, cycle: int, raw: int, session: int, mode: Mode) -> can.Message:
        """FfCommand frame (see :meth:`encode_command`)."""
        return can.Message(
            arbitration_id=self.command.frame_id,
            data=self.encode_command(cycle, raw, session, mode),
            is_extended_id=False,
        )

    def check_command(self, data: bytes) -> Command | None:
        """The fields of an intact command frame whose values are all in range, else None."""
        if len(data) != self.command.length or not _crc_holds(data, self.command_data_id):
            return None
        fields = _decode_raw(self.command, data)
        for name, (low, high) in self._ranges.items():  # decoding does no range check
            if not low <= fields[name] <= high:
                return None
        return Command(fields["Cycle"], fields["Current"], fields["Session"], Mode(fields["Mode"]))

    def status_frame(
        self, cycle: int, applied_raw: int, session: int, state: int, rejected: int
    ) -> can.Message:
        """DriveStatus frame of drive cycle ``cycle`` (just run)."""
        data = self.status.encode(
            {
                "Crc": 0,
                "Cycle": cycle % STAMP_MODULUS,
                "AppliedCurrent": applied_raw,
                "Session": session,
                "State": state,
                "Rejected": rejected % 64,
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
            f["Cycle"], self.from_raw(f["AppliedCurrent"]), f["Session"], f["State"], f["Rejected"]
        )


def _raw_range(signal: Any) -> tuple[int, int]:
    if signal.minimum is None or signal.maximum is None:
        raise cantools.database.Error(f"signal {signal.name} needs a minimum and a maximum")
    scale = float(signal.scale)
    return round(signal.minimum / scale), round(signal.maximum / scale)


def _data_id(message: Message) -> int:
    attributes: Any = message.dbc.attributes if message.dbc is not None else {}
    return int(attributes["E2EDataId"].value)


def _decode_raw(message: Message, data: bytes) -> dict[str, int]:
    fields: Any = message.decode(data, scaling=False, decode_choices=False)
    return {name: int(value) for name, value in fields.items()}
