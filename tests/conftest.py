"""Shared test set-up: the ``slow`` marker on long tests, and a copy of the checkout.

``python -m pytest -q -n auto`` (the README's command, what .ci/run calls) runs every test,
on every core (pytest-xdist, one test file per worker);
``python -m pytest -q -m "not slow"`` skips those marked ``slow`` (over ~20 s each on a
loaded 2-core machine) for a quicker local run. Tests in this project's own helper
files carry ``@pytest.mark.slow``; the long tests listed in :data:`SLOW` are marked
here so that their modules stay as their owners wrote them.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# Test functions (all their parameters) over ~20 s, by file; measured with --durations.
SLOW: dict[str, frozenset[str]] = {
    "test_diagnosis.py": frozenset(
        {
            "test_hidden_effect_is_named_with_its_parameter",  # 7-27 s for each of 9 effects
            "test_no_effect_on_effect_free_traces",  # 10-19 s for each of 3 seeds
            "test_cli_writes_spec_keys_and_a_loadable_table",  # 32 s
            "test_unlike_gms_falls_back_to_free_nnls",  # 24 s
        }
    ),
    "test_sweep.py": frozenset({"test_local_cluster_gives_the_serial_result"}),  # 23-32 s
    "test_fleet.py": frozenset({"test_local_cluster_gives_the_serial_rows"}),  # 15-75 s
    "test_can_processes.py": frozenset({"test_stream_to_an_emulator_in_another_process"}),  # 18 s
}


@pytest.hookimpl(tryfirst=True)  # before -m "not slow" deselects
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark the tests of :data:`SLOW` as ``slow``."""
    for item in items:
        names = SLOW.get(item.path.name)
        if names and getattr(item, "originalname", item.name) in names:
            item.add_marker(pytest.mark.slow)


def tracked_files() -> list[str]:
    """The files a clean clone of the checkout holds (tracked, plus new untracked ones)."""
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout: cannot tell which files a clone would hold")
    listed = subprocess.run(
        ["git", "ls-files", "--cached", "--others", "--exclude-standard", "-z"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return [name for name in listed.split("\0") if name]


def copy_checkout(target: Path) -> Path:
    """Copy the files of a clean clone of the checkout into ``target``; return it."""
    for name in tracked_files():
        source = ROOT / name
        if not source.exists() and not source.is_symlink():
            continue  # deleted in the work tree, not yet committed
        dest = target / name
        dest.parent.mkdir(parents=True, exist_ok=True)
        if source.is_symlink():
            dest.symlink_to(os.readlink(source))
        else:
            shutil.copy2(source, dest)
    return target


@pytest.fixture(scope="session")
def checkout_copier() -> Callable[[Path], Path]:
    """:func:`copy_checkout`, for tests that need the checkout as a clean clone has it."""
    return copy_checkout
