"""Worst-case bus load of classic CAN frames.

A classic frame with an 11-bit identifier and ``n`` data bytes has 34 + 8n bits
between start of frame and the CRC that are subject to bit stuffing (at worst one
stuff bit after every four, the first one after five), and 13 fixed-form bits
(CRC delimiter, ACK, end of frame, intermission): 135 bits for 8 data bytes.
"""

from __future__ import annotations

from collections.abc import Iterable

from gms_comp.errors import BusError

MAX_BUS_LOAD = 0.70
_STUFFED_OVERHEAD_BITS = {False: 34, True: 54}  # SOF..CRC without data, by extended id
_FIXED_BITS = 13


def frame_bits_worst_case(data_bytes: int, *, extended_id: bool = False) -> int:
    """Bits on the wire of one classic CAN frame with worst-case stuffing."""
    if not 0 <= data_bytes <= 8:
        raise ValueError(f"classic CAN carries 0..8 data bytes, got {data_bytes}")
    stuffed = _STUFFED_OVERHEAD_BITS[extended_id] + 8 * data_bytes
    return stuffed + _FIXED_BITS + (stuffed - 1) // 4


def bus_load(traffic: Iterable[tuple[int, float]], bitrate_bit_s: float) -> float:
    """Fraction of the bit rate used by ``(data_bytes, frames_per_s)`` streams."""
    bits_per_s = sum(frame_bits_worst_case(n) * rate for n, rate in traffic)
    return bits_per_s / bitrate_bit_s


def check_bus_load(load: float, limit: float = MAX_BUS_LOAD) -> None:
    """Refuse a configuration whose worst-case load exceeds ``limit``."""
    if load > limit:
        raise BusError(
            f"worst-case bus load {100 * load:.1f} % exceeds {100 * limit:.0f} %: "
            "lower the cycle rate, raise the bit rate or reduce other traffic"
        )
