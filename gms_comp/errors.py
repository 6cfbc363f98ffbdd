"""One exception root for the project; every subclass also subclasses a builtin.

The CLI turns any :class:`GmsCompError` into a one-line message and exit code 2.
"""

from __future__ import annotations


class GmsCompError(Exception):
    """Root of all errors raised deliberately by gms-comp."""


class ConfigError(GmsCompError, ValueError):
    """A configuration file is unreadable or holds a bad value.

    The message names the file, the key and the reason.
    """

    def __init__(self, path: str, key: str, reason: str) -> None:
        self.path = path
        self.key = key
        self.reason = reason
        where = f"{path}: {key}" if key else path
        super().__init__(f"{where}: {reason}")


class TableError(GmsCompError, ValueError):
    """A GMS table file is truncated, of an unknown version, or holds bad values."""


class TraceError(GmsCompError, ValueError):
    """A measured trace cannot be used (missing columns, NaN, time not increasing, ...)."""


class ScenarioError(GmsCompError, ValueError):
    """A simulation scenario is inconsistent."""


class BusError(GmsCompError, RuntimeError):
    """The CAN link cannot be set up or used as configured."""
