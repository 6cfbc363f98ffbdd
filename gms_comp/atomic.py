"""One atomic writer for every file gms-comp writes.

A file is written to a uniquely named temporary file in the target's own folder,
flushed and fsync'ed, then moved over the target with :func:`os.replace`. A run that
fails or is killed at any point leaves the earlier file, if any, as it was, and no two
writers share a temporary name.

Several files that belong together (a diagnosis report and its table) are written as one
set (:func:`replaced_folder`): into a new hidden folder renamed into place at the end, the
old set moved aside before anything of the new one is written, so that a run killed at any
moment never leaves a new file beside an old set that looks complete.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path

from gms_comp.errors import InputError


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it replaces ``path``.

    For writers that want a file name (``savefig``, ``np.save``, a BLF logger).
    The temporary file keeps ``path``'s suffix so that writers choosing a format by
    suffix choose the same one. On any exception the temporary file is removed and
    ``path`` is untouched.

    Examples
    --------
    >>> with atomic_path("out/fig.png") as tmp:  # doctest: +SKIP
    ...     fig.savefig(tmp)
    """
    target = Path(path)
    fd, name = tempfile.mkstemp(
        prefix=f".{target.name}.", suffix=f".tmp{target.suffix}", dir=target.parent or "."
    )
    os.close(fd)
    tmp = Path(name)
    # mkstemp makes the file private (0600); give it the mode the target has, or the
    # one a plain open() would give a new file (0666 less the umask).
    with contextlib.suppress(OSError):
        os.chmod(tmp, _mode_for(target))
    try:
        yield tmp
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp, target)
        _fsync_dir(target.parent)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; return the path written."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; return the path written."""
    return write_bytes(path, text.encode("utf-8"))


def _mode_for(target: Path) -> int:
    """The permission bits for ``target``: its current ones, else 0666 less the umask."""
    try:
        return stat.S_IMODE(target.stat().st_mode)
    except OSError:
        pass
    return 0o666 & ~_umask()


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _fsync_dir(folder: Path) -> None:
    """Make the rename itself durable (POSIX; a no-op where folders cannot be opened)."""
    with contextlib.suppress(OSError):
        fd = os.open(folder or ".", os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


#: The file a set of files is vouched for by, written last (:func:`replaced_folder`).
SET_MANIFEST = "manifest.json"


@contextlib.contextmanager
def replaced_folder(path: str | os.PathLike[str], marker: str = SET_MANIFEST) -> Iterator[Path]:
    """Write a folder as one set: yield a new empty folder; on success it becomes ``path``.

    Before the body runs, the folder at ``path`` (if any) is moved aside to a hidden
    ``.NAME.*.old`` beside it, so that whatever the body writes elsewhere (a table named
    on the command line) never sits beside the old set; on success the new folder is
    renamed to ``path`` and the old one removed; on an exception the new one is removed
    and the old one put back. A kill leaves ``path`` absent or complete (and the hidden
    folders behind, removed by the next run that completes). The body writes ``marker``
    (the set's manifest) last.

    Raises
    ------
    InputError
        When ``path`` holds files but no ``marker``: it is not a set this function wrote,
        and is not replaced.
    """
    target = Path(path)
    check_replaceable(target, marker)
    parent = target.parent
    parent.mkdir(parents=True, exist_ok=True)
    new = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".partial", dir=parent))
    with contextlib.suppress(OSError):  # mkdtemp's 0700, as a plain mkdir would make it
        os.chmod(new, 0o777 & ~_umask())
    old: Path | None = None
    try:
        if target.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".old", dir=parent))
            os.rename(target, old)  # onto the empty folder just made: one rename
        yield new
        os.rename(new, target)
        _fsync_dir(parent)
        for stale in (
            *parent.glob(f".{target.name}.*.partial"),
            *parent.glob(f".{target.name}.*.old"),
        ):
            if stale != old:  # what killed runs left behind: the new set is complete now
                shutil.rmtree(stale, ignore_errors=True)
    except BaseException:
        shutil.rmtree(new, ignore_errors=True)
        if old is not None and not target.exists():
            os.rename(old, target)
            old = None
        raise
    finally:
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)


def check_replaceable(folder: Path, marker: str = SET_MANIFEST) -> None:
    """Refuse to replace ``folder`` when it holds files but not ``marker``."""
    if folder.is_dir() and any(folder.iterdir()) and not (folder / marker).is_file():
        raise InputError(
            str(folder), "", f"holds files but no {marker}: not a set gms-comp wrote, so it is "
            "not replaced; give a new or empty folder",
        )  # fmt: skip
