"""The ``[can]`` config section: how the feedforward travels to the drive.

Times are in seconds and currents in amperes; the conversion to CAN units
(per mille, 0.1 mA steps, milliseconds in the object dictionary) happens in the
profile codecs only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import can

from firmware_bridge.profiles import PROFILES
from gms_comp.config import (
    default_config_path,
    in_range,
    parse_section,
    positive,
    read_toml,
)

MIN_CYCLE_S = 1e-4  # 10 kHz: beyond what classic CAN carries, and the loop's time budget
AUTO = "auto"
FALLBACK_INTERFACE, FALLBACK_CHANNEL = "virtual", "gms-comp"
ProfileName = str  # a key of firmware_bridge.profiles.PROFILES


def _registered(value: object) -> str | None:
    return None if value in PROFILES else f"must be one of {', '.join(map(repr, PROFILES))}"


@dataclass(frozen=True)
class CanConfig:
    """Transport of the feedforward current from the compensator to the drive.

    ``rx_timeout_s`` is how long the drive holds the last valid value before it
    declares the link lost; it then ramps the offset to zero over at most
    ``ramp_time_s``, so the feedforward is zero ``rx_timeout_s + ramp_time_s``
    after the last valid frame. The streamer uses the same ramp on stop or fault.

    ``interface`` and ``channel`` are python-can's; ``"auto"`` takes python-can's own
    configuration (``CAN_INTERFACE``, ``CAN_CHANNEL``, ``~/.canrc``), as its tools do, and
    without one the ``virtual`` interface on channel ``gms-comp``.

    ``sync_master`` (cia402): the compensator produces SYNC; when false, the NC
    does and the compensator sends one RPDO in answer to each SYNC, which the
    drive applies at the next SYNC. ``heartbeat_period_s`` is the period of both
    heartbeats, the compensator's (consumed by the drive, 0x1016) and the
    drive's (0x1017).
    """

    profile: ProfileName = field(default="cia402", metadata={"check": _registered})
    interface: str = AUTO
    channel: str = AUTO
    bitrate_bit_s: int = field(default=1_000_000, metadata=in_range(10_000, 8_000_000))
    cycle_period_s: float = field(default=1e-3, metadata=in_range(MIN_CYCLE_S, 1.0))
    max_current_A: float = field(default=1.0, metadata=in_range(1e-3, 1e3))
    ramp_time_s: float = field(default=5e-3, metadata=positive(10.0))
    rx_timeout_s: float = field(default=3e-3, metadata=in_range(1e-4, 10.0))
    max_frame_age_cycles: int = field(default=1, metadata=in_range(0, 16))
    drive_node_id: int = field(default=1, metadata=in_range(1, 127))
    compensator_node_id: int = field(default=16, metadata=in_range(1, 127))
    sync_master: bool = True
    heartbeat_period_s: float = field(default=0.1, metadata=in_range(1e-3, 60.0))
    rated_current_A: float = field(default=2.0, metadata=in_range(1e-3, 1e3))
    background_load: float = field(default=0.0, metadata=in_range(0.0, 1.0, hi_open=True))
    status_every_cycles: int = field(default=1, metadata=in_range(1, 1000))

    def problems(self) -> list[tuple[str, str]]:
        """`rx_timeout_s`, `ramp_time_s` and `heartbeat_period_s` >= `cycle_period_s`;
        `compensator_node_id` differs from `drive_node_id`.

        Returns the inconsistencies as ``(key, reason)`` pairs.
        """
        found = []
        for name in ("rx_timeout_s", "ramp_time_s", "heartbeat_period_s"):
            if getattr(self, name) < self.cycle_period_s:
                found.append((name, f"must be >= cycle_period_s ({self.cycle_period_s:g} s)"))
        if self.drive_node_id == self.compensator_node_id:
            found.append(("compensator_node_id", "must differ from drive_node_id"))
        return found

    @property
    def timeout_cycles(self) -> int:
        """Whole cycles the drive holds a value before declaring the link lost."""
        return cycles_within(self.rx_timeout_s, self.cycle_period_s)

    @property
    def ramp_cycles(self) -> int:
        """Whole cycles a full-scale ramp to zero may take."""
        return cycles_within(self.ramp_time_s, self.cycle_period_s)

    @property
    def fallback_time_s(self) -> float:
        """Upper bound from the last valid frame to a zero feedforward."""
        return (self.timeout_cycles + self.ramp_cycles) * self.cycle_period_s


def resolved(cfg: CanConfig) -> CanConfig:
    """``cfg`` with ``"auto"`` interface and channel taken from python-can's configuration
    (environment, ``~/.canrc``), else the ``virtual`` interface on ``gms-comp``."""
    if AUTO not in (cfg.interface, cfg.channel):
        return cfg
    try:
        found: dict[str, Any] = dict(can.util.load_config())
    except (can.CanError, ValueError, OSError):
        found = {}
    interface = found.get("interface") or FALLBACK_INTERFACE
    channel = found.get("channel") or FALLBACK_CHANNEL
    return replace(
        cfg,
        interface=interface if cfg.interface == AUTO else cfg.interface,
        channel=str(channel) if cfg.channel == AUTO else cfg.channel,
    )


def cycles_within(duration_s: float, period_s: float) -> int:
    """Number of whole periods that fit in ``duration_s`` (at least one)."""
    return max(1, math.floor(duration_s / period_s + 1e-9))


def load_can_config(path: str | Path | None = None) -> CanConfig:
    """Load the ``[can]`` section of ``path`` (default: the packaged config), ``"auto"``
    interface and channel resolved (:func:`resolved`)."""
    p = Path(path) if path is not None else default_config_path()
    return resolved(parse_section(read_toml(p), p, "can", CanConfig))
