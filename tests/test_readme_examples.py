"""Every ``gms-comp`` line of the README's Examples block runs as written (issue 11).

The lines run in order (later ones read what earlier ones wrote) in a copy of the
checkout as a clean clone holds it, with ``../shared`` beside it when the shared data
exist. Each must exit 0 and leave the files it names (``-o``, ``--report``, ``--plot``,
``--log``, ``--table``, a ``--json`` followed by a file) and the files it says it wrote
(``wrote PATH``).
"""

from __future__ import annotations

import itertools
import os
import re
import shlex
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
LINE_TIMEOUT_S = 900
# Options whose value is a file or folder the command writes.
WRITE_OPTIONS = ("-o", "--output", "--report", "--plot", "--log", "--table", "--json")


def readme_examples(readme: str) -> list[str]:
    """The ``gms-comp`` lines of the first code block under ``## Examples``."""
    section = readme.split("\n## Examples", 1)[1]
    block = section.split("```", 2)[1]
    return [line.strip() for line in block.splitlines() if line.strip().startswith("gms-comp ")]


def named_outputs(line: str) -> list[str]:
    """The paths a line names after an output option (globs and comments left out)."""
    words = shlex.split(line, comments=True)
    found = []
    for option, value in itertools.pairwise(words):
        if option in WRITE_OPTIONS and not value.startswith("-") and "*" not in value:
            found.append(value)
    return found


def announced(output: str) -> list[str]:
    """The paths of ``wrote PATH`` lines (``wrote PATH: ...`` too)."""
    return [m.group(1) for m in re.finditer(r"^wrote (\S+?):?(?:\s|$)", output, re.MULTILINE)]


def test_examples_are_found() -> None:
    lines = readme_examples((ROOT / "README.md").read_text(encoding="utf-8"))
    assert lines and lines[0].startswith("gms-comp model")
    assert named_outputs("gms-comp table -o out/t.json --elements 16 --json") == ["out/t.json"]
    assert named_outputs("gms-comp diagnose m.csv --json out/d.json --report out/d") == [
        "out/d.json",
        "out/d",
    ]
    assert announced("wrote out/a.png\nwrote out/t.json: 16 elements\n") == [
        "out/a.png",
        "out/t.json",
    ]


@pytest.mark.slow
def test_readme_examples_run_as_written(
    tmp_path: Path, checkout_copier: Callable[[Path], Path]
) -> None:
    repo = checkout_copier(tmp_path / "gms-comp")
    if SHARED.is_dir():
        (tmp_path / "shared").symlink_to(SHARED)
    # `gms-comp` is this test environment's, whatever its console scripts folder is.
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    launcher = bin_dir / "gms-comp"
    launcher.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m gms_comp "$@"\n')
    launcher.chmod(0o755)
    env = {**os.environ, "PATH": f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}"}
    env.pop("PYTHONPATH", None)

    lines = readme_examples((repo / "README.md").read_text(encoding="utf-8"))
    for number, line in enumerate(lines, 1):
        if "../shared/" in line and not SHARED.is_dir():
            continue  # the shared data are not beside this checkout (tests skip then too)
        try:
            result = subprocess.run(
                ["bash", "-c", line],
                cwd=repo,
                env=env,
                capture_output=True,
                text=True,
                timeout=LINE_TIMEOUT_S,
                check=False,
            )
        except subprocess.TimeoutExpired as err:
            pytest.fail(f"README example {number} ran over {LINE_TIMEOUT_S} s: {line}\n{err}")
        where = f"README example {number}: {line}"
        assert result.returncode == 0, (
            f"{where}\nexit {result.returncode}\nstderr:\n{result.stderr[-4000:]}"
        )
        written = named_outputs(line) + announced(result.stdout + result.stderr)
        missing = [p for p in written if not (repo / p).exists()]
        assert not missing, f"{where}\nnamed or announced but not written: {missing}"
