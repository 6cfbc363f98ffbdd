"""Opening a python-can bus from the ``[can]`` section, with a one-line error."""

from __future__ import annotations

import logging

import can

from firmware_bridge.settings import CanConfig, resolved
from gms_comp.errors import BusError

VCAN_HINT = "create one with: ip link add dev vcan0 type vcan && ip link set up vcan0"
LIBRARY_HINTS = {
    "kvaser": "the Kvaser CANlib driver and library (canlib32) from kvaser.com",
    "pcan": "the PEAK PCAN-Basic driver and library from peak-system.com",
    "vector": "the Vector XL Driver Library (vxlapi) from vector.com",
    "ixxat": "the IXXAT VCI driver from hms-networks.com",
    "nican": "the National Instruments NI-CAN driver",
    "gs_usb": "the Python package pyusb (pip install pyusb) and libusb",
    "serial": "the Python package pyserial (pip install pyserial)",
    "slcan": "the Python package pyserial (pip install pyserial)",
}


def open_bus(cfg: CanConfig) -> can.BusABC:
    """A bus handle on the configured interface and channel.

    Parameters
    ----------
    cfg
        The ``[can]`` section (interface, channel, bit rate).

    Returns
    -------
    can.BusABC
        The open bus; the caller closes it.

    Raises
    ------
    BusError
        If python-can cannot open it; for socketcan, with how to create a vcan.
    """
    cfg = resolved(cfg)
    logger = logging.getLogger("can")
    level = logger.level
    logger.setLevel(logging.ERROR)  # a backend's "library unavailable" warning: said below
    try:
        return can.Bus(interface=cfg.interface, channel=cfg.channel, bitrate=cfg.bitrate_bit_s)
    except Exception as err:  # a backend without its library fails in any way
        hint = ""
        if cfg.interface == "socketcan":
            hint = f"; for a virtual SocketCAN channel {VCAN_HINT.replace('vcan0', cfg.channel)}"
        elif cfg.interface in LIBRARY_HINTS:
            hint = f"; this interface needs {LIBRARY_HINTS[cfg.interface]}"
        raise BusError(
            f"cannot open CAN interface {cfg.interface!r} channel {cfg.channel!r}: "
            f"{' '.join(str(err).split())}{hint}"
        ) from err
    finally:
        logger.setLevel(level)
