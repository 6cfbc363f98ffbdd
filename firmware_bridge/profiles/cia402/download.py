"""Downloading a GMS table into a drive that runs the observer itself (SDO, CiA 301).

The table file (JSON, as ``gms-comp table`` and ``diagnose --table`` write it) goes into
the DOMAIN object 0x2100 by SDO block transfer (segmented where the drive has no block
transfer), after its CRC-32 into 0x2101; the drive refuses a table whose CRC, content or
size does not fit with an SDO abort, and 0x2102 tells the elements it loaded
(:mod:`.in_drive`).
"""

from __future__ import annotations

import canopen
from canopen.sdo.exceptions import SdoAbortedError, SdoCommunicationError

from firmware_bridge.profiles.cia402.codec import load_drive_od
from firmware_bridge.profiles.cia402.in_drive import (
    TABLE_CRC,
    TABLE_LOADED,
    TABLE_OBJECT,
    table_crc,
)
from firmware_bridge.settings import CanConfig, resolved
from gms_comp.errors import BusError

SDO_TIMEOUT_S = 2.0


def download_table(cfg: CanConfig, data: bytes) -> int:
    """Download ``data`` (a table file) into drive ``cfg.drive_node_id``; the elements loaded.

    Raises
    ------
    BusError
        One line: the drive refused the table (its SDO abort code says why) or did not
        answer.
    """
    cfg = resolved(cfg)
    network = canopen.Network()
    try:
        network.connect(interface=cfg.interface, channel=cfg.channel, bitrate=cfg.bitrate_bit_s)
        node = canopen.RemoteNode(cfg.drive_node_id, load_drive_od(cfg.drive_node_id))
        node.sdo.RESPONSE_TIMEOUT = SDO_TIMEOUT_S
        network.add_node(node)
        node.sdo.download(TABLE_CRC, 0, table_crc(data).to_bytes(4, "little"))
        try:
            with node.sdo.open(TABLE_OBJECT, 0, "wb", size=len(data), block_transfer=True) as f:
                f.write(data)
        except SdoAbortedError as err:
            if err.code != 0x05040001:  # not "command not supported": a refusal
                raise
            node.sdo.download(TABLE_OBJECT, 0, data, force_segment=True)
        return int.from_bytes(node.sdo.upload(TABLE_LOADED, 0), "little")
    except SdoAbortedError as err:
        raise BusError(
            f"drive node {cfg.drive_node_id} refused the table ({len(data)} bytes): SDO abort "
            f"0x{err.code:08X} ({_ABORTS.get(err.code, 'see CiA 301')})"
        ) from None
    except SdoCommunicationError as err:
        raise BusError(
            f"drive node {cfg.drive_node_id} did not answer the download: {err}"
        ) from None
    finally:
        network.disconnect()


_ABORTS = {
    0x05040005: "out of memory: the table does not fit the drive",
    0x08000020: "not stored: CRC mismatch or not a table",
    0x06010002: "read only",
    0x06020000: "no such object: the drive runs no observer",
}


def store_table(node: canopen.LocalNode, data: bytes) -> int:
    """The download's effect on a drive in this process (a stepped run, where no SDO client
    can wait for the drive): the same objects written, the same checks. Elements loaded."""
    try:
        node.set_data(TABLE_CRC, 0, table_crc(data).to_bytes(4, "little"))
        node.set_data(TABLE_OBJECT, 0, data)
    except SdoAbortedError as err:
        raise BusError(f"the drive refused the table: SDO abort 0x{err.code:08X}") from None
    return int.from_bytes(node.get_data(TABLE_LOADED, 0), "little")
