"""A wheel built from the checkout installs and runs outside it (issue 11).

The rest of the suite runs against the editable install, which hides packages or data
files a wheel leaves out. Here the wheel is built from a copy of the tracked files
(as from a clean clone), installed with ``--no-deps`` into a fresh venv that sees the
test environment's packages (numpy, numba, ...), and run from a folder outside the
checkout. Nothing is downloaded: the build uses the installed setuptools
(``--no-build-isolation``).
"""

from __future__ import annotations

import json
import os
import site
import subprocess
import sys
import sysconfig
from collections.abc import Callable
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TIMEOUT_S = 600


def _run(args: list[str | Path], cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    result = subprocess.run(
        [str(a) for a in args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
        check=False,
    )
    assert result.returncode == 0, f"{args} failed:\n{result.stdout}\n{result.stderr}"
    return result


@pytest.fixture(scope="module")
def venv(tmp_path_factory: pytest.TempPathFactory, checkout_copier: Callable[[Path], Path]) -> Path:
    """A fresh venv with the wheel installed; returns its bin folder."""
    pytest.importorskip("setuptools", reason="setuptools is needed to build the wheel")
    pytest.importorskip("wheel", reason="wheel is needed to build the wheel")
    base = tmp_path_factory.mktemp("wheel")
    source = checkout_copier(base / "src")
    dist = base / "dist"
    build: list[str | Path] = [sys.executable, "-m", "pip", "wheel", "-q", "-w", dist]
    _run([*build, "--no-deps", "--no-build-isolation", "--no-index", source], cwd=base)
    (wheel,) = dist.glob("gms_comp-*.whl")
    env_dir = base / "venv"
    _run([sys.executable, "-m", "venv", "--system-site-packages", env_dir], cwd=base)
    bin_dir = env_dir / ("Scripts" if os.name == "nt" else "bin")
    # The test environment's own packages (numpy, numba, ...) when it is itself a venv:
    # plain path entries, so its editable install of gms_comp is not activated.
    purelib = Path(
        _run(
            [bin_dir / "python", "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
            cwd=base,
        ).stdout.strip()
    )
    outer = {sysconfig.get_path("purelib"), *site.getsitepackages()} - {str(purelib)}
    (purelib / "_gms_comp_test_env.pth").write_text(
        "".join(f"{p}\n" for p in sorted(outer) if Path(p).is_dir()), encoding="utf-8"
    )
    _run(
        [bin_dir / "python", "-m", "pip", "install", "--no-deps", "--no-index", "-q", wheel],
        cwd=base,
    )
    return bin_dir


@pytest.fixture(scope="module")
def outside(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A working folder outside the checkout."""
    return tmp_path_factory.mktemp("outside")


def test_package_imported_from_the_venv_with_its_data(venv: Path, outside: Path) -> None:
    probe = """
import json
from importlib import resources
import gms_comp, firmware_bridge, sim, gms_comp.measured.diagnosis
files = {
    "dbc": resources.files("firmware_bridge") / "gms_ff.dbc",
    "eds": resources.files("firmware_bridge") / "cia402_drive.eds",
    "c": resources.files("firmware_bridge") / "c" / "ff_handler.c",
    "h": resources.files("firmware_bridge") / "c" / "ff_handler.h",
    "config": resources.files("gms_comp.configs") / "table1.toml",
    "typed": resources.files("gms_comp") / "py.typed",
}
print(json.dumps({
    "module": gms_comp.__file__,
    "files": {k: v.is_file() for k, v in files.items()},
    "config_head": files["config"].read_text()[:200],
}))
"""
    data = json.loads(_run([venv / "python", "-c", probe], cwd=outside).stdout)
    venv_root = venv.parent.resolve()
    assert Path(data["module"]).resolve().is_relative_to(venv_root), data["module"]
    assert not Path(data["module"]).resolve().is_relative_to(ROOT)
    assert data["files"] == dict.fromkeys(data["files"], True), data["files"]
    assert "Table 1" in data["config_head"]


def test_every_subcommand_help_runs(venv: Path, outside: Path) -> None:
    top = _run([venv / "gms-comp", "--help"], cwd=outside).stdout
    assert "usage: gms-comp" in top
    # The subcommands the installed CLI registers, so a new one is covered by itself.
    listing = (
        "import argparse; from gms_comp.app.cli import build_parser; "
        "sub = next(a for a in build_parser()._actions "
        "if isinstance(a, argparse._SubParsersAction)); print(' '.join(sub.choices))"
    )
    names = _run([venv / "python", "-c", listing], cwd=outside).stdout.split()
    assert {"model", "table", "diagnose", "simulate", "stream", "config"} <= set(names)
    # One interpreter for all of them: each --help imports the same modules.
    probe = f"""
import contextlib, io, sys
from gms_comp.app.cli import main
for name in {names!r}:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        try:
            main([name, "--help"])
        except SystemExit as stop:
            assert stop.code == 0, (name, stop.code)
    assert out.getvalue().startswith(f"usage: gms-comp {{name}}"), (name, out.getvalue())
    print(name)
"""
    done = _run([venv / "python", "-c", probe], cwd=outside).stdout.split()
    assert done == names
    for name in names:
        assert f"    {name}" in top, f"{name} missing from gms-comp --help"


def test_model_json_from_the_installed_cli(venv: Path, outside: Path) -> None:
    result = _run([venv / "gms-comp", "model", "--json"], cwd=outside)
    data = json.loads(result.stdout)
    # /work/shared/spec/physics.md: Table 1's contact, a = 65.157 um, b = 307.177 um.
    assert data["contact"]["a_m"] == pytest.approx(65.157e-6, rel=1e-4)
    assert data["contact"]["b_m"] == pytest.approx(307.177e-6, rel=1e-4)
    assert not Path(data["config"]).resolve().is_relative_to(ROOT)


def test_module_entry_point_and_config_defaults(venv: Path, outside: Path) -> None:
    text = _run([venv / "python", "-m", "gms_comp", "config", "--defaults"], cwd=outside).stdout
    (outside / "defaults.toml").write_text(text, encoding="utf-8")
    check = _run([venv / "gms-comp", "config", "defaults.toml"], cwd=outside).stdout
    assert "valid" in check
