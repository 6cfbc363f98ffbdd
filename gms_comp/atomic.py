"""One atomic writer for every file gms-comp writes.

A file is written to a uniquely named temporary file in the target's own folder,
flushed and fsync'ed, then moved over the target with :func:`os.replace`. A run that
fails or is killed at any point leaves the earlier file, if any, as it was, and no two
writers share a temporary name.
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path


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
    mask = os.umask(0o022)
    os.umask(mask)
    return 0o666 & ~mask


def _fsync_dir(folder: Path) -> None:
    """Make the rename itself durable (POSIX; a no-op where folders cannot be opened)."""
    with contextlib.suppress(OSError):
        fd = os.open(folder or ".", os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
