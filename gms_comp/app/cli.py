"""The ``gms-comp`` command line.

Each subcommand lives in ``gms_comp.app.commands.<name>`` and exposes
``register(subparsers)``, which adds its parser and sets ``func`` to a callable
taking the parsed namespace and returning the exit code. Bad input raised as
:class:`~gms_comp.errors.GmsCompError` becomes one line on stderr and exit code 2;
Ctrl-C, wherever it lands (importing the subcommands, parsing, running), one line
and exit code 130, SIGTERM one line and exit code 143, both after every file being
written has been removed (the atomic writer's temporary files, a frame log) and a Dask
cluster shut down quietly; a closed stdout (``| head``) ends the run quietly with exit
code 1.

Every subcommand follows one convention: ``--json`` prints the result as JSON on
stdout and nothing else there; without it a short human summary goes to stdout.
Files are written only where an option names them (``-o/--output``, ``--plot DIR``,
...), each announced by one ``wrote PATH`` line (on stderr under ``--json``).
"""

from __future__ import annotations

import _thread
import argparse
import importlib
import os
import signal
import sys
import threading
from collections.abc import Sequence
from typing import TYPE_CHECKING, NoReturn

if TYPE_CHECKING:
    from sys import UnraisableHookArgs

from pathlib import Path

from gms_comp import __version__
from gms_comp.arguments import PathArgument, PathRole, check_paths
from gms_comp.errors import GmsCompError

# One line per subcommand, each a module gms_comp.app.commands.<name> with register().
SUBCOMMANDS: tuple[str, ...] = (
    "model",
    "config",
    "diagnose",
    "profile",
    "demo_trace",
    "sweep",
    "stream",
    "machine",
    "record",
    "run",
    "commission",
    "simulate",
    "replay",
    "table",
    "bench",
    "export_c",
)

INTERRUPTED = 130  # the shell's code for a process ended by SIGINT
TERMINATED = 143  # ... and by SIGTERM


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread like Ctrl-C so that every ``finally`` and
    context manager on the way out runs (temporary files removed, clusters closed)."""


def _terminate(_signum: int, _frame: object) -> None:
    raise Terminated


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose refusals are one line (no usage block), exit code 2."""

    def error(self, message: str) -> NoReturn:
        """Print ``PROG: error: MESSAGE (see PROG --help)`` on stderr and exit 2."""
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``gms-comp`` parser with every subcommand of :data:`SUBCOMMANDS` registered, or
    only ``command``'s when it names one: a run imports its own module alone (``gms-comp
    diagnose`` starts in 1.1 s instead of 2.1 s, the other commands' simulation and
    plotting stacks unloaded)."""
    parser = OneLineParser(
        prog="gms-comp",
        description="Friction compensation for linear-motor axes with ball guides.",
    )
    parser.add_argument("--version", action="version", version=f"gms-comp {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    module = (command or "").replace("-", "_")
    for name in (module,) if module in SUBCOMMANDS else SUBCOMMANDS:
        importlib.import_module(f"gms_comp.app.commands.{name}").register(sub)
    for subparser in sub.choices.values():
        subparser.set_defaults(path_arguments=_path_arguments(subparser))
    return parser


def _path_arguments(parser: argparse.ArgumentParser) -> tuple[tuple[str, str, PathRole], ...]:
    """``(dest, option, role)`` of each path argument of ``parser`` (its type a
    :class:`~gms_comp.arguments.PathArgument`)."""
    return tuple(
        (a.dest, "/".join(a.option_strings) or a.metavar or a.dest, a.type.role)  # type: ignore[misc]
        for a in parser._actions
        if isinstance(a.type, PathArgument)
    )


def _given_paths(args: argparse.Namespace) -> list[tuple[str, PathRole, Path]]:
    """The paths given on the command line, with their option and role."""
    found: list[tuple[str, PathRole, Path]] = []
    for dest, option, role in getattr(args, "path_arguments", ()):
        value = getattr(args, dest, None)
        for item in value if isinstance(value, list) else [value]:
            if isinstance(item, Path):
                found.append((option, role, item))
    return found


def _command(argv: Sequence[str]) -> str | None:
    """The subcommand ``argv`` names: its first word that is not an option (the top level
    has no option that takes a value)."""
    return next((arg for arg in argv if not arg.startswith("-")), None)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``gms-comp`` with ``argv`` (default: the process arguments); return the exit code."""
    deliver_lost_interrupts()
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _terminate) if main_thread else None
    command = "gms-comp"
    try:
        words = sys.argv[1:] if argv is None else list(argv)
        try:
            args = build_parser(_command(words)).parse_args(words)
        except SystemExit as done:  # --help, --version, or a refusal (one line, code 2)
            return done.code if isinstance(done.code, int) else 2
        command = f"gms-comp {args.command}"
        check_paths(_given_paths(args))  # before any work: no output over an input
        code: int = args.func(args)
        if _REDELIVERY["lost"]:  # lost, and its thread has not run yet
            raise KeyboardInterrupt
    except GmsCompError as err:
        print(f"{command}: error: {err}", file=sys.stderr)
        return 2
    except (KeyboardInterrupt, RuntimeError) as err:
        # Python wraps an interrupt raised in a class's __set_name__ (a dataclass being
        # created while a command's module is imported) in a RuntimeError
        if isinstance(err, RuntimeError) and not isinstance(err.__cause__, KeyboardInterrupt):
            raise
        _REDELIVERY["armed"] = False  # interrupted once is enough
        quiet_finalizers()
        # SIGTERM: the handler's Terminated, or a run that stops in order (app.signals)
        terminated = isinstance(err, Terminated) or isinstance(err.__cause__, Terminated)
        code = TERMINATED if terminated else _code(err)
        print(
            f"{command}: {'terminated' if code == TERMINATED else 'interrupted'}", file=sys.stderr
        )
        return code
    except BrokenPipeError:  # the reader of stdout went away (`gms-comp ... | head`)
        _silence_stdout()
        return 1
    finally:
        _REDELIVERY["armed"] = False
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    return code


def _code(err: BaseException) -> int:
    code: int = getattr(err, "exit_code", INTERRUPTED)
    return code


# Whether a lost interrupt is delivered again (until the run is over or interrupted),
# and whether one was lost and not yet delivered.
_REDELIVERY = {"armed": False, "lost": False}


def _redeliver() -> None:
    if _REDELIVERY["armed"]:
        _REDELIVERY["lost"] = False
        _thread.interrupt_main()


def deliver_lost_interrupts() -> None:
    """Interrupt the main thread again when a Ctrl-C's KeyboardInterrupt is lost. Raised
    inside a finalizer or a ctypes callback, it is reported as unraisable and dropped,
    and the run goes on to its end: in a fresh-clone CI run, ``gms-comp bench``
    interrupted 1 s after start exited 0, its stderr showing the KeyboardInterrupt
    "ignored on calling ctypes callback function" (llvmlite's object-cache notifier,
    while numba loaded its cache); not reproduced in 24 tries after. The hook hands the
    interrupt to a new thread, which trips SIGINT for the main thread once the callback
    has returned (``interrupt_main`` called from the hook itself raises inside the hook,
    and that is dropped too). Other unraisable errors go to the hook that was there
    before; installed once per process, armed until :func:`main` returns or is
    interrupted (an interrupt it has handled is not delivered again)."""
    _REDELIVERY.update(armed=True, lost=False)
    previous = sys.unraisablehook
    if getattr(previous, "redelivers_interrupts", False):
        return

    def hook(unraisable: UnraisableHookArgs) -> None:
        if isinstance(unraisable.exc_value, KeyboardInterrupt) and _REDELIVERY["armed"]:
            _REDELIVERY["lost"] = True
            try:
                _thread.start_new_thread(_redeliver, ())
                return
            except RuntimeError:  # no new threads at interpreter shutdown
                pass
        previous(unraisable)

    hook.redelivers_interrupts = True  # type: ignore[attr-defined]
    sys.unraisablehook = hook


def quiet_finalizers() -> None:
    """Drop the errors of finalizers from now on: Ctrl-C can land inside a constructor
    (llvmlite's, while numba compiles), and the half-built object's ``__del__`` then fails
    when it is collected, which Python reports as an "Exception ignored" traceback."""
    sys.unraisablehook = lambda _unraisable: None


def _silence_stdout() -> None:
    """Point stdout at /dev/null so that the interpreter's final flush does not fail again."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
