"""Command-line values and paths: checked when the arguments are parsed, before any work.

Numbers come with their range (:func:`int_in_range`, :func:`float_in_range`); paths with
what the run does with them (:class:`PathArgument`: read, written, written into, replaced),
so that the CLI refuses, before the work starts, an output that is an input of the run, two
outputs that are one file, an output that is not a regular file (a FIFO, a device, an entry
of /proc or /dev) and an input inside a folder the run replaces (:func:`check_paths`). A
format chosen by suffix is checked here too, not found wrong after minutes of work.
"""

from __future__ import annotations

import argparse
import math
import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from gms_comp.atomic import check_replaceable
from gms_comp.errors import InputError


def int_in_range(lo: int, hi: int) -> Callable[[str], int]:
    """An argparse ``type``: an integer in [lo, hi]."""

    def parse(value: str) -> int:
        try:
            number = int(value)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer, got {value!r}") from None
        if not lo <= number <= hi:
            raise argparse.ArgumentTypeError(f"must be in [{lo}, {hi}], got {number}")
        return number

    parse.__name__ = "integer"
    return parse


def float_in_range(lo: float, hi: float, *, lo_open: bool = False) -> Callable[[str], float]:
    """An argparse ``type``: a finite number in [lo, hi] ((lo, hi] when ``lo_open``)."""

    def parse(value: str) -> float:
        try:
            number = float(value)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a number, got {value!r}") from None
        above = lo < number if lo_open else lo <= number
        if not (math.isfinite(number) and above and number <= hi):
            lower = "(" if lo_open else "["
            raise argparse.ArgumentTypeError(f"must be in {lower}{lo:g}, {hi:g}], got {value}")
        return number

    parse.__name__ = "number"
    return parse


_ADDRESS = re.compile(r"^(tcp|tls)://(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+)(:(\d{1,5}))?$")


def scheduler_address(value: str) -> str:
    """An argparse ``type``: a Dask scheduler address ``tcp://host:port`` or ``tls://...``."""
    found = _ADDRESS.match(value.strip())
    if found is None:
        raise argparse.ArgumentTypeError(
            f"{value!r} is not a scheduler address (expected tls://HOST:PORT or tcp://HOST:PORT)"
        )
    port = found.group(4)
    if port is not None and not 0 < int(port) < 65536:
        raise argparse.ArgumentTypeError(f"{value!r}: port must be in [1, 65535]")
    return value.strip()


#: Folders whose entries are not files a run may write or replace (devices, processes,
#: kernel state): an output there is refused, whatever the permissions.
SYSTEM_FOLDERS = ("/dev", "/proc", "/sys")
#: The suffixes of a plot file (``--plot``): the formats matplotlib writes by suffix.
PLOT_SUFFIXES = (".png", ".pdf", ".svg", ".eps", ".jpg", ".jpeg", ".tif", ".tiff", ".webp")

PathRole = Literal["input", "output", "folder", "replaced folder"]


@dataclass(frozen=True)
class PathArgument:
    """An argparse ``type`` for a path a run reads or writes.

    ``role`` says what the run does with it, so that the command line's paths are checked
    together before any work (:func:`check_paths`): ``"input"`` is read, ``"output"`` is
    a file written (replaced atomically), ``"folder"`` a folder written into,
    ``"replaced folder"`` a folder written as one set and put in place of the old one.
    """

    role: PathRole
    parse: Callable[[str], Path]
    __name__: str = "path"

    def __call__(self, value: str) -> Path:
        """The checked path (an ``argparse.ArgumentTypeError`` when it is refused)."""
        return self.parse(value)


def _system_entry(path: Path) -> str | None:
    """The system folder ``path`` lies in, as written or once its links are resolved."""
    for candidate in (path.absolute(), Path(os.path.realpath(path))):
        for folder in SYSTEM_FOLDERS:
            if candidate == Path(folder) or Path(folder) in candidate.parents:
                return folder
    return None


def _writable_file(value: str) -> Path:
    """A file to be written: not a folder, not a FIFO, device or socket (which an atomic
    replace would turn into a regular file), nothing under /dev, /proc or /sys, in an
    existing writable folder."""
    path = Path(value)
    if value == "" or path.is_dir():
        raise argparse.ArgumentTypeError(f"{value!r} is a folder, expected a file name")
    system = _system_entry(path)
    if system is not None:
        raise argparse.ArgumentTypeError(
            f"{value!r} is under {system}: write to a regular file (--json prints to stdout)"
        )
    if path.exists() and not path.is_file():
        raise argparse.ArgumentTypeError(
            f"{value!r} exists and is not a regular file (a FIFO, device or socket): "
            "it would be replaced, not written"
        )
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise argparse.ArgumentTypeError(f"{value!r}: folder {str(folder)!r} does not exist")
    if not os.access(folder, os.W_OK):
        raise argparse.ArgumentTypeError(f"{value!r}: folder {str(folder)!r} is not writable")
    return path


def _writable_folder(value: str) -> Path:
    """A folder to write into: it exists as a folder or can be created (its nearest
    existing ancestor is a writable folder), not under /dev, /proc or /sys."""
    path = Path(value)
    if value == "":
        raise argparse.ArgumentTypeError("empty folder name")
    system = _system_entry(path)
    if system is not None:
        raise argparse.ArgumentTypeError(f"{value!r} is under {system}: not a folder to write")
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


def _readable_file(value: str) -> Path:
    path = Path(value)
    if not path.is_file():
        what = "is a folder" if path.is_dir() else "does not exist (file not found)"
        if path.exists() and not path.is_dir():
            what = "is not a regular file"
        raise argparse.ArgumentTypeError(f"{value!r} {what}")
    return path


def suffixed_file(suffixes: tuple[str, ...], what: str) -> PathArgument:
    """An output file whose suffix (case-insensitive) is one of ``suffixes``: the format
    is known before the run, not found wrong after it."""

    def parse(value: str) -> Path:
        path = _writable_file(value)
        if path.suffix.lower() not in suffixes:
            got = f"suffix {path.suffix!r}" if path.suffix else "no suffix"
            raise argparse.ArgumentTypeError(
                f"{value!r} has {got}: a {what} is written as {', '.join(suffixes)}"
            )
        return path

    return PathArgument("output", parse)


#: An argparse ``type`` for a file to be written (see :func:`_writable_file`).
output_file = PathArgument("output", _writable_file)
#: An argparse ``type`` for a folder to write files into.
output_dir = PathArgument("folder", _writable_folder)


def _replaceable_folder(value: str) -> Path:
    path = _writable_folder(value)
    try:
        check_replaceable(path)
    except InputError as err:
        raise argparse.ArgumentTypeError(f"{value!r} {err.problem}") from None
    return path


#: An argparse ``type`` for a folder written as one set, replacing the old one at the end
#: (:func:`gms_comp.atomic.replaced_folder`): new, empty, or a set gms-comp wrote.
replaced_dir = PathArgument("replaced folder", _replaceable_folder)
#: An argparse ``type`` for a file to be read: it exists and is a regular file.
input_file = PathArgument("input", _readable_file)
#: An argparse ``type`` for a plot to be written: a suffix matplotlib writes.
plot_file = suffixed_file(PLOT_SUFFIXES, "plot")


def check_paths(paths: list[tuple[str, PathRole, Path]]) -> None:
    """Refuse a command line whose outputs could hurt its inputs, before any work.

    ``paths`` holds ``(option, role, path)`` for every path argument given. Refused:
    an output that is an input (the same file, by inode or by its resolved path: a
    link, a hard link, ``./x``), two outputs that are one file, and an input inside a
    folder the run replaces.
    """
    inputs = [(o, p) for o, r, p in paths if r == "input"]
    outputs = [(o, p) for o, r, p in paths if r == "output"]
    replaced = [(o, p) for o, r, p in paths if r == "replaced folder"]
    for i, (option, out) in enumerate(outputs):
        for other, path in inputs + outputs[:i]:
            if _same_file(out, path):
                kind = "an input" if (other, path) in inputs else "another output"
                raise InputError(
                    option, "", f"{str(out)!r} is {kind} of this run ({other}): it would be "
                    "overwritten; write to another file",
                )  # fmt: skip
    for option, folder in replaced:
        root = Path(os.path.realpath(folder))
        for other, path in inputs:
            if root in Path(os.path.realpath(path)).parents:
                raise InputError(
                    option, "", f"{str(folder)!r} holds {str(path)!r}, an input of this run "
                    f"({other}): the folder is replaced at the end; write to another folder",
                )  # fmt: skip


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist yet
        return os.path.realpath(a) == os.path.realpath(b)
