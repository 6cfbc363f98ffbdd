"""One validation layer for everything that comes from outside.

Configs, tables, traces, sweep files and command-line values are untrusted. Every
refusal is an :class:`InputError`: one line ``SOURCE: FIELD: PROBLEM`` (the file or
the option, the key/row/column, what is wrong), turned by the CLI into exit code 2.

The command-line helpers here check output paths when the arguments are parsed, so that
a run never computes for minutes and then fails to write its result.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from .errors import GmsCompError


class InputError(GmsCompError, ValueError):
    """Bad input from outside: names its source, the field and the problem."""

    def __init__(self, source: str, field: str, problem: str) -> None:
        self.source = str(source)
        self.field = field
        self.problem = problem
        where = f"{self.source}: {field}" if field else self.source
        super().__init__(f"{where}: {problem}")


def output_file(value: str) -> Path:
    """An argparse ``type`` for a file to be written: its folder exists and is writable,
    and the path is not a folder."""
    path = Path(value)
    if value == "" or path.is_dir():
        raise argparse.ArgumentTypeError(f"{value!r} is a folder, expected a file name")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise argparse.ArgumentTypeError(f"{value!r}: folder {str(folder)!r} does not exist")
    if not os.access(folder, os.W_OK):
        raise argparse.ArgumentTypeError(f"{value!r}: folder {str(folder)!r} is not writable")
    return path


def output_dir(value: str) -> Path:
    """An argparse ``type`` for a folder to write into: it exists as a folder or can be
    created (its nearest existing ancestor is a writable folder)."""
    path = Path(value)
    if value == "":
        raise argparse.ArgumentTypeError("empty folder name")
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{value!r} is a file, expected a folder")
    ancestor = path
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise argparse.ArgumentTypeError(f"{value!r}: {str(ancestor)!r} is a file")
    if not os.access(ancestor, os.W_OK):
        raise argparse.ArgumentTypeError(f"{value!r}: {str(ancestor)!r} is not writable")
    return path


def input_file(value: str) -> Path:
    """An argparse ``type`` for a file to be read: it exists and is a file."""
    path = Path(value)
    if not path.is_file():
        what = "is a folder" if path.is_dir() else "does not exist"
        raise argparse.ArgumentTypeError(f"{value!r} {what}")
    return path
