"""Outputs that cannot hurt: no output over an input or a non-regular file, sets written
as one, signals that leave nothing half-written, resumes only of unchanged configs.

The command-line refusals themselves (each of the audit's cases through a real
``gms-comp`` process) are in tests/test_fuzz_inputs.py, classes ``outputs`` and
``scheduler``; here: the rules behind them, the report set under injected failures and
kills, SIGTERM/SIGINT on a frame log and on a Dask run, and the sweep's resume.
"""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gms_comp.app.cli import main
from gms_comp.app.report_set import input_record, write_report_set
from gms_comp.arguments import check_paths
from gms_comp.atomic import SET_MANIFEST
from gms_comp.config import default_config_path
from gms_comp.errors import InputError
from gms_comp.gms import GmsParams
from gms_comp.tables.table import Fidelity, GmsTable, read_table

ROOT = Path(__file__).resolve().parents[1]


def test_an_output_that_is_an_input_by_any_name_is_refused(tmp_path: Path) -> None:
    config = tmp_path / "c.toml"
    config.write_text("x")
    (tmp_path / "hard.toml").hardlink_to(config)
    (tmp_path / "soft.toml").symlink_to(config)
    for alias in ("c.toml", "hard.toml", "soft.toml", "./sub/../c.toml"):
        (tmp_path / "sub").mkdir(exist_ok=True)
        paths = [("config", "input", config), ("-o", "output", tmp_path / alias)]
        with pytest.raises(InputError, match="is an input of this run"):
            check_paths(paths)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="another output"):
        check_paths([("--log", "output", tmp_path / "f.csv"), ("-o", "output", tmp_path / "f.csv")])
    report = tmp_path / "rep"
    with pytest.raises(InputError, match="the folder is replaced"):
        check_paths([("TRACE", "input", report / "t.csv"), ("--report", "replaced folder", report)])
    check_paths([("TRACE", "input", config), ("-o", "output", tmp_path / "new.json")])


def _table(level: float) -> GmsTable:
    params = GmsParams(stiffness_N_per_m=np.array([1e5]), limit_N=np.array([level]), slip_level=1.1)
    return GmsTable(params, "t.csv", "0" * 64, Fidelity(0.01, 0.02))


def _fake_report(pause_s: float = 0.0, fail_after: int | None = None) -> Any:
    """A stand-in for the report's plots and page: three files, a pause before each."""

    def write_report(_diagnosis: Any, doc: Any, folder: Path) -> list[Path]:
        written = []
        for i, name in enumerate(("residual.png", "phases.png", "index.html")):
            if fail_after is not None and i == fail_after:
                raise OSError("disk full")
            time.sleep(pause_s)
            (folder / name).write_text(f"{name} of {json.dumps(doc['inputs'])}")
            written.append(folder / name)
        return written

    return write_report


def _set_state(report: Path, table: Path) -> str:
    """``complete <trace>`` when the manifest vouches for every file, else what is wrong."""
    manifest = report / SET_MANIFEST
    if not manifest.exists():
        return "absent" if not report.exists() else "folder without manifest"
    doc = json.loads(manifest.read_text())
    import hashlib

    for name, digest in doc["files"].items():
        path = Path(name) if os.path.isabs(name) else report / name
        if hashlib.sha256(path.read_bytes()).hexdigest() != digest:
            return f"mismatch {name}"
    return "complete " + Path(doc["inputs"]["trace"]["path"]).name


def test_a_failure_between_writes_keeps_the_old_set(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import gms_comp.app.report as report_module

    trace_a, trace_b = tmp_path / "a.csv", tmp_path / "b.csv"
    trace_a.write_text("a")
    trace_b.write_text("b")
    report, table = tmp_path / "rep", tmp_path / "T.json"
    monkeypatch.setattr(report_module, "write_report", _fake_report())
    write_report_set(None, report, input_record({"trace": trace_a}), _table(0.1), table, {})  # type: ignore[arg-type]
    old = {p.name: p.read_bytes() for p in report.iterdir()}
    old_table = table.read_bytes()
    assert _set_state(report, table) == "complete a.csv"
    for fail_after in (0, 1, 2):
        monkeypatch.setattr(report_module, "write_report", _fake_report(fail_after=fail_after))
        with pytest.raises(OSError, match="disk full"):
            write_report_set(None, report, input_record({"trace": trace_b}), _table(0.2), table, {})  # type: ignore[arg-type]
        assert {p.name: p.read_bytes() for p in report.iterdir()} == old
        assert table.read_bytes() == old_table  # the new table never sits beside the old set
        assert sorted(p.name for p in tmp_path.iterdir()) == ["T.json", "a.csv", "b.csv", "rep"]
    monkeypatch.setattr(report_module, "write_report", _fake_report())
    files = write_report_set(None, report, input_record({"trace": trace_b}), _table(0.2), table, {})  # type: ignore[arg-type]
    assert _set_state(report, table) == "complete b.csv"
    assert read_table(table).params.limit_N[0] == 0.2 and files[0] == table
    manifest = json.loads((report / SET_MANIFEST).read_text())
    assert manifest["inputs"]["trace"]["path"] == str(trace_b)
    assert "b.csv" in (report / "index.html").read_text()  # each file names its inputs


KILLER = """
import sys
from pathlib import Path
import gms_comp.app.report as report_module
sys.path.insert(0, {tests!r})
from test_outputs_safe import _fake_report, _table
from gms_comp.app.report_set import input_record, write_report_set
report_module.write_report = _fake_report(pause_s=0.05)
trace = Path(sys.argv[1])
write_report_set(None, Path("rep"), input_record({{"trace": trace}}), _table(float(sys.argv[2])),
                 Path("T.json"), {{}})
"""


@pytest.mark.slow
def test_a_kill_at_any_moment_leaves_no_mixed_set(tmp_path: Path) -> None:
    """SIGKILL at random moments of the writing (seeded): the report is the old complete
    set, absent, or the new complete set; the table beside it is always its own."""
    script = tmp_path / "writer.py"
    script.write_text(KILLER.format(tests=str(Path(__file__).parent)))
    for name in ("a.csv", "b.csv"):
        (tmp_path / name).write_text(name)
    run = [sys.executable, str(script)]
    subprocess.run([*run, "a.csv", "0.1"], cwd=tmp_path, check=True, timeout=60)
    started = time.monotonic()
    subprocess.run([*run, "b.csv", "0.2"], cwd=tmp_path, check=True, timeout=60)
    full_s = time.monotonic() - started
    rng = random.Random(74)
    states = []
    for i in range(12):
        proc = subprocess.Popen([*run, "ab"[i % 2] + ".csv", str(0.1 + i)], cwd=tmp_path)
        time.sleep(rng.uniform(0.3, 1.0) * full_s)
        proc.kill()
        proc.wait()
        states.append(_set_state(tmp_path / "rep", tmp_path / "T.json"))
    assert all(s == "absent" or s.startswith("complete") for s in states), states


def test_sigterm_on_a_frame_log_leaves_no_temporary_file(tmp_path: Path) -> None:
    """``stream --log``: SIGTERM mid-stream is a clean stop (ramp, release) ending in one
    line and exit code 143; the log of that stream is in place, no temporary file beside."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "gms_comp", "stream", "--duration", "30", "--log", "f.asc"],
        cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    deadline = time.monotonic() + 60
    while not list(tmp_path.glob(".f.asc.*")) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert list(tmp_path.glob(".f.asc.*")), "the temporary log never appeared"
    time.sleep(4.0)  # well into the stream (the observer's set-up takes ~2.5 s)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    assert err.strip().splitlines()[-1].startswith("gms-comp stream: stopped by SIGTERM"), err
    assert "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.asc"]


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_during_a_dask_run_is_one_line(tmp_path: Path, sig: signal.Signals) -> None:
    """Ctrl-C or SIGTERM while a local cluster computes: one line, exit 130 or 143, no
    Dask warnings, asyncio tracebacks or leaked-semaphore warnings."""
    sweep = tmp_path / "s.toml"
    sweep.write_text(
        f'[sweep]\nbase_config = "{default_config_path()}"\nelements = 4\n'
        '[sweep.axes]\n"stand.ball_loads_N" = [30.0, 40.0, 50.0, 60.0]\n'
    )
    proc = subprocess.Popen(
        [sys.executable, "-m", "gms_comp", "sweep", str(sweep), "--workers", "1", "-o", "fam"],
        cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    deadline = time.monotonic() + 120
    while not (tmp_path / "fam" / "manifest.json").exists() and time.monotonic() < deadline:
        time.sleep(0.2)  # the manifest is written once the cluster is up, before the jobs
    time.sleep(1.0)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    expected = {signal.SIGINT: (130, "interrupted"), signal.SIGTERM: (143, "terminated")}[sig]
    assert (proc.returncode, err.strip()) == (expected[0], f"gms-comp sweep: {expected[1]}"), err


def test_a_sweep_resumes_only_points_whose_whole_config_is_unchanged(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    sweep = tmp_path / "s.toml"

    def run(elements: int) -> dict[str, Any]:
        sweep.write_text(
            f'[sweep]\nbase_config = "{default_config_path()}"\nelements = {elements}\n'
            '[sweep.axes]\n"stand.ball_loads_N" = [50.0]\n'
        )
        assert main(["sweep", str(sweep), "--serial", "-o", str(tmp_path / "fam")]) == 0
        capsys.readouterr()
        point: dict[str, Any] = json.loads((tmp_path / "fam" / "manifest.json").read_text())[
            "points"
        ][0]
        return point

    first = run(1)
    assert not first.get("resumed")
    changed = run(2)  # another elements on the command line of the sweep: recomputed
    assert not changed.get("resumed") and "changed" in changed["note"]
    assert read_table(tmp_path / "fam" / changed["table"]).n_elements == 2
    assert run(2)["resumed"] is True


def test_the_checked_suffixes_are_formats_the_writers_have() -> None:
    """A suffix the CLI accepts is one matplotlib and python-can write (so the check before
    the work and the writer after it agree)."""
    import can.io.logger
    import matplotlib.pyplot as plt

    from firmware_bridge.frame_log import LOG_SUFFIXES
    from gms_comp.arguments import PLOT_SUFFIXES

    assert set(LOG_SUFFIXES) <= set(can.io.logger.MESSAGE_WRITERS)
    figure = plt.figure()
    assert {s[1:] for s in PLOT_SUFFIXES} <= set(figure.canvas.get_supported_filetypes())
    plt.close(figure)
