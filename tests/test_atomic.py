"""The atomic writer: a good file is never replaced by a partial one, even under kill -9.

A child process writes a large file over a good one, chunk by chunk, and reports each
chunk on stdout; the test kills it with SIGKILL after a random number of chunks (and
at random times around the final rename). Afterwards the target must be the old file
or the complete new one, byte for byte. The same harness with a plain ``open(..., "wb")``
writer must catch a partial file, which shows that the check can fail.
"""

from __future__ import annotations

import hashlib
import os
import random
import signal
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from gms_comp.atomic import atomic_path, write_bytes, write_text

CHUNK = 1 << 20
CHUNKS = 24  # a 24 MB file

_WRITER = r"""
import os, sys
from pathlib import Path
from gms_comp.atomic import atomic_path

target, mode = Path(sys.argv[1]), sys.argv[2]
chunk = bytes(range(256)) * (int(sys.argv[3]) // 256)
count = int(sys.argv[4])
pause = int(sys.argv[5])  # wait here (for the kill) after this chunk; -1: never
print("ready", flush=True)

def write(f):
    for i in range(count):
        f.write(chunk)
        f.flush()
        print(i, flush=True)
        if i == pause:
            sys.stdin.readline()

if mode == "atomic":
    with atomic_path(target) as tmp, open(tmp, "wb") as f:
        write(f)
else:
    with open(target, "wb") as f:
        write(f)
print("done", flush=True)
"""


def _new_digest() -> str:
    return hashlib.sha256((bytes(range(256)) * (CHUNK // 256)) * CHUNKS).hexdigest()


def _kill_after(target: Path, mode: str, lines: int, extra_s: float, pause: bool = False) -> None:
    """Run the writer, kill it with SIGKILL after ``lines`` progress lines + ``extra_s``
    (with ``pause``, the writer waits there for the kill: on a loaded machine it could
    otherwise finish the file before the kill lands)."""
    at = lines - 2 if pause else -1  # the chunk whose line is the ``lines``-th
    proc = subprocess.Popen(
        [sys.executable, "-c", _WRITER, str(target), mode, str(CHUNK), str(CHUNKS), str(at)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    for seen, _line in enumerate(proc.stdout, start=1):
        if seen >= lines:
            break
    if extra_s:
        time.sleep(extra_s)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    proc.stdout.close()
    if proc.stdin is not None:
        proc.stdin.close()


def _state(target: Path, old: bytes, new_digest: str) -> str:
    data = target.read_bytes()
    if data == old:
        return "old"
    if hashlib.sha256(data).hexdigest() == new_digest:
        return "new"
    return f"partial ({len(data)} bytes)"


def test_kill_9_never_leaves_a_partial_file(tmp_path: Path) -> None:
    rng = random.Random(13)
    target = tmp_path / "table.json"
    old = b'{"good": "file"}\n' * 1000
    new_digest = _new_digest()
    outcomes = []
    # Kill points: after 1 .. CHUNKS + 2 progress lines ("ready", chunks, "done"), and a
    # random delay so some kills land inside fsync / os.replace.
    points = [rng.randint(1, CHUNKS + 2) for _ in range(10)] + [CHUNKS + 1, CHUNKS + 2]
    for lines in points:
        target.write_bytes(old)
        _kill_after(target, "atomic", lines, rng.uniform(0.0, 0.05))
        state = _state(target, old, new_digest)
        assert state in ("old", "new"), f"killed after {lines} lines: {state}"
        outcomes.append(state)
    assert "old" in outcomes  # the kills did land before the rename


def test_the_kill_harness_catches_a_plain_writer(tmp_path: Path) -> None:
    target = tmp_path / "table.json"
    old = b"good\n" * 1000
    target.write_bytes(old)
    _kill_after(target, "plain", CHUNKS // 2, 0.0, pause=True)
    state = _state(target, old, _new_digest())
    assert state == f"partial ({(CHUNKS // 2 - 1) * CHUNK} bytes)", state


def test_failed_write_leaves_the_old_file_and_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "out.json"
    target.write_text("old\n")
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("half")
        raise RuntimeError("writer failed")
    assert target.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]


def test_temporary_names_are_unique_and_beside_the_target(tmp_path: Path) -> None:
    target = tmp_path / "manifest.json"
    with atomic_path(target) as a, atomic_path(target) as b:
        assert a != b
        assert a.parent == b.parent == tmp_path
        assert a.suffix == ".json"  # writers choosing a format by suffix see the same one
        a.write_text("first")
        b.write_text("second")
    assert target.read_text() == "first"  # the outer one replaced last


def test_concurrent_writers_into_one_folder_never_mix(tmp_path: Path) -> None:
    target = tmp_path / "manifest.json"
    texts = [f"writer {i}\n" * 20_000 for i in range(6)]
    errors: list[BaseException] = []

    def run(text: str) -> None:
        try:
            for _ in range(5):
                write_text(target, text)
        except BaseException as err:  # collected for the assertion below
            errors.append(err)

    threads = [threading.Thread(target=run, args=(t,)) for t in texts]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert target.read_text() in texts
    assert [p.name for p in tmp_path.iterdir()] == ["manifest.json"]


def test_new_files_get_the_usual_mode_and_existing_ones_keep_theirs(tmp_path: Path) -> None:
    mask = os.umask(0o022)
    try:
        fresh = write_bytes(tmp_path / "fresh.bin", b"x")
        assert stat.S_IMODE(fresh.stat().st_mode) == 0o644
        kept = tmp_path / "kept.bin"
        kept.write_bytes(b"old")
        kept.chmod(0o600)
        write_bytes(kept, b"new")
        assert stat.S_IMODE(kept.stat().st_mode) == 0o600
    finally:
        os.umask(mask)
