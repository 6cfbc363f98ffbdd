"""The CAN profiles, one sub-package each, registered by name in :data:`PROFILES`.

A profile is everything that depends on how the feedforward reaches a drive:
its codec, the compensator's sending side, the drive's receiving side (what the
emulator runs, and a firmware implements) and which ``[can]`` keys it uses. The
rest of :mod:`firmware_bridge` (streamer, emulator, session, CLI) reaches a
profile only through :func:`firmware_bridge.profiles.base.get_profile` and the small
interface in :mod:`firmware_bridge.profiles.base`.

Adding a profile: a new sub-package whose ``__init__`` defines ``PROFILE`` (an
object implementing :class:`~firmware_bridge.profiles.base.Profile`), and one
line in :data:`PROFILES`. As in python-can's interface table, the table names
modules, which are imported on first use.
"""

from __future__ import annotations

PROFILES: dict[str, str] = {
    "cia402": "firmware_bridge.profiles.cia402",  # standard servo drive, 0x60B2 torque offset
    "e2e": "firmware_bridge.profiles.e2e",  # custom firmware, DBC frame with CRC and counter
}
"""Profile name -> the module defining its ``PROFILE``."""
