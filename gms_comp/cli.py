"""The ``gms-comp`` command line.

Each subcommand lives in ``gms_comp.commands.<name>`` and exposes
``register(subparsers)``, which adds its parser and sets ``func`` to a callable
taking the parsed namespace and returning the exit code. Bad input raised as
:class:`~gms_comp.errors.GmsCompError` becomes one line on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from . import __version__
from .errors import GmsCompError

SUBCOMMANDS: tuple[str, ...] = (
    "model",
    "diagnose",
    "profile",
    "demo_trace",
    "sweep",
    "stream",
    "simulate",
    "table",
    "bench",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="gms-comp",
        description="Friction compensation for linear-motor axes with ball guides.",
    )
    parser.add_argument("--version", action="version", version=f"gms-comp {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in SUBCOMMANDS:
        importlib.import_module(f"gms_comp.commands.{name}").register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        code: int = args.func(args)
    except GmsCompError as err:
        print(f"gms-comp {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"gms-comp {args.command}: interrupted", file=sys.stderr)
        return 130
    return code


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
