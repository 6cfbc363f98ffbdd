"""A run that must end in order on Ctrl-C or SIGTERM: the signal asks, the run stops itself.

A stream to a drive cannot simply be killed: it ramps the feedforward to zero and
releases the drive first. Inside :func:`stop_requests`, SIGINT and SIGTERM raise
:class:`Stopped` (an interrupt the CLI reports with the signal's exit code, 130 or
143), except while the run defers them (:meth:`StopRequest.deferred`, around the loop
that talks to the drive): there they set a request the loop polls, and the command
exits with the same code after its clean stop.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field
from types import FrameType


class Stopped(KeyboardInterrupt):
    """SIGINT or SIGTERM while nothing needed a clean stop."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum

    @property
    def exit_code(self) -> int:
        """128 + the signal's number: 130 for SIGINT, 143 for SIGTERM."""
        return 128 + self.signum


@dataclass
class StopRequest:
    """What the first SIGINT or SIGTERM asked, while :func:`stop_requests` is active."""

    event: threading.Event = field(default_factory=threading.Event)
    signum: int | None = None
    _deferring: bool = False

    @property
    def name(self) -> str:
        """``SIGINT`` or ``SIGTERM`` (empty while not set)."""
        return signal.Signals(self.signum).name if self.signum is not None else ""

    @property
    def exit_code(self) -> int:
        """128 + the signal's number: 130 for SIGINT (also a Ctrl-C seen as an interrupt)."""
        return 128 + (self.signum or signal.SIGINT)

    @contextlib.contextmanager
    def deferred(self) -> Iterator[threading.Event]:
        """Inside, a signal sets the yielded event instead of raising."""
        self._deferring = True
        try:
            yield self.event
        finally:
            self._deferring = False

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        if self.signum is None:
            self.signum = signum
        self.event.set()
        if not self._deferring:
            raise Stopped(signum)


@contextlib.contextmanager
def stop_requests() -> Iterator[StopRequest]:
    """Install the handlers of SIGINT and SIGTERM for the block (main thread only; the
    previous handlers come back on exit)."""
    request = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield request
        return
    previous = {sig: signal.signal(sig, request._handle) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield request
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
