"""Opening a python-can bus from the ``[can]`` section, with a one-line error."""

from __future__ import annotations

import can

from firmware_bridge.settings import CanConfig
from gms_comp.errors import BusError

VCAN_HINT = "create one with: ip link add dev vcan0 type vcan && ip link set up vcan0"


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
    try:
        return can.Bus(interface=cfg.interface, channel=cfg.channel, bitrate=cfg.bitrate_bit_s)
    except (can.CanError, ImportError, OSError, ValueError) as err:
        hint = ""
        if cfg.interface == "socketcan":
            hint = f"; for a virtual SocketCAN channel {VCAN_HINT.replace('vcan0', cfg.channel)}"
        raise BusError(
            f"cannot open CAN interface {cfg.interface!r} channel {cfg.channel!r}: "
            f"{' '.join(str(err).split())}{hint}"
        ) from err
