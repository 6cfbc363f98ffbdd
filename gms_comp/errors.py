"""One exception root for the project; every subclass also subclasses a builtin.

The CLI turns any :class:`GmsCompError` into a one-line message and exit code 2.
Bad input from outside is an :class:`InputError` (or one of its subclasses
:class:`ConfigError`, :class:`TableError`, :class:`TraceError`): one line
``SOURCE: FIELD: PROBLEM``.
"""

from __future__ import annotations


class GmsCompError(Exception):
    """Root of all errors raised deliberately by gms-comp."""


class InputError(GmsCompError, ValueError):
    """Bad input from outside: names its source, the field and the problem.

    Parameters
    ----------
    source
        The file or the command-line option the value came from.
    field
        The key, row or column inside the source ("" when the whole source is bad).
    problem
        What is wrong, and where useful what to do instead. Given alone (one
        argument), ``source`` is taken as the complete message (older call sites).
    """

    def __init__(self, source: str, field: str = "", problem: str | None = None) -> None:
        self.source = str(source)
        self.field = field
        if problem is None:
            self.problem = self.source
            super().__init__(" ".join(self.source.split()))
            return
        self.problem = problem
        where = f"{self.source}: {field}" if field else self.source
        # One line, whatever a parser or a file name put into the message.
        super().__init__(" ".join(f"{where}: {problem}".split()))


class ConfigError(InputError):
    """A configuration file is unreadable or holds a bad value.

    The message names the file, the key and the reason.
    """

    def __init__(self, path: str, key: str, reason: str) -> None:
        self.path = path
        self.key = key
        self.reason = reason
        super().__init__(path, key, reason)


class TableError(InputError):
    """A GMS table file is truncated, of an unknown version, or holds bad values."""


class TraceError(InputError):
    """A measured trace cannot be used (missing columns, NaN, time not increasing, ...)."""


class ScenarioError(GmsCompError, ValueError):
    """A simulation scenario is inconsistent."""


class BusError(GmsCompError, RuntimeError):
    """The CAN link cannot be set up or used as configured."""
