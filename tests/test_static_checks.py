"""The tree stays ruff- and mypy-clean: the same checks a reviewer would run."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(args: list[str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(args, cwd=ROOT, capture_output=True, text=True, check=False)


@pytest.mark.skipif(shutil.which("ruff") is None, reason="ruff is not installed")
def test_ruff_is_clean() -> None:
    result = _run(["ruff", "check", "--no-cache", "."])
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.skipif(shutil.which("ruff") is None, reason="ruff is not installed")
def test_ruff_format_is_applied() -> None:
    result = _run(["ruff", "format", "--check", "--no-cache", "."])
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.slow  # about a minute
def test_mypy_is_clean() -> None:
    pytest.importorskip("mypy", reason="mypy is not installed")
    result = _run([sys.executable, "-m", "mypy"])
    assert result.returncode == 0, result.stdout + result.stderr


def test_slow_list_names_existing_tests() -> None:
    """A renamed test must not silently lose its ``slow`` mark (tests/conftest.py)."""
    from conftest import SLOW

    for file_name, names in SLOW.items():
        text = (ROOT / "tests" / file_name).read_text(encoding="utf-8")
        for name in names:
            assert f"def {name}(" in text, f"tests/conftest.py SLOW: {file_name}::{name} not found"


def test_slow_marker_is_registered() -> None:
    """``-m "not slow"`` needs the marker declared (pytest warns about unknown ones)."""
    import tomllib

    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    markers = config["tool"]["pytest"]["ini_options"]["markers"]
    assert any(m.startswith("slow:") for m in markers)
