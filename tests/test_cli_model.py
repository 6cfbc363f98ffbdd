"""`gms-comp model`: the JSON keys the issue names, in SI units, and the text summary;
the CLI convention shared by model, table and the rest (paths checked at parsing, Ctrl-C)."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from matplotlib.figure import Figure

import gms_comp.app.plots_physics as plots
from gms_comp.app import cli
from gms_comp.app.cli import main
from gms_comp.config import default_config_path

ROOT = Path(__file__).resolve().parents[1]


def _json(capsys: pytest.CaptureFixture[str], argv: list[str]) -> dict[str, Any]:
    assert main(argv) == 0
    data: dict[str, Any] = json.loads(capsys.readouterr().out)
    return data


def test_json_keys_and_values(capsys: pytest.CaptureFixture[str]) -> None:
    data = _json(capsys, ["model", "--json"])
    assert data["contact"]["a_m"] == pytest.approx(65.157e-6, rel=1e-3)
    assert data["contact"]["b_m"] == pytest.approx(307.177e-6, rel=1e-3)
    assert data["contact"]["p0_Pa"] == pytest.approx(1192.8e6, rel=1e-3)
    assert data["contact"]["approach_m"] == pytest.approx(2.0484e-6, rel=1e-3)
    assert data["rolling_lines"]["beta"] == pytest.approx(0.347, abs=0.005)
    assert data["rolling_lines"]["lambda"] >= 1.0
    beta, b, r = data["rolling_lines"]["beta"], data["contact"]["b_m"], 3.175e-3
    assert data["rolling_lines"]["xi0"] == pytest.approx(
        -((beta * b) ** 2) / (2 * r**2 - (beta * b) ** 2)
    )
    assert data["friction"]["sliding_force_N"] == pytest.approx(0.277, abs=2e-3)


def test_explicit_config_equals_default(capsys: pytest.CaptureFixture[str]) -> None:
    implicit = _json(capsys, ["model", "--json"])
    explicit = _json(capsys, ["model", str(default_config_path()), "--json"])
    assert implicit == explicit


def test_ball_set_sums_its_balls(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = (
        default_config_path()
        .read_text()
        .replace("ball_loads_N = [50.0, 50.0, 50.0, 50.0]", "ball_loads_N = [50.0, 100.0]")
    )
    path = tmp_path / "two.toml"
    path.write_text(text)
    data = _json(capsys, ["model", str(path), "--json"])
    per_ball = data["friction"]["sliding_force_per_ball_N"]
    assert len(per_ball) == 2
    assert math.isclose(sum(per_ball), data["friction"]["sliding_force_N"])
    # Friction grows with load (the traction limit integrates to C_v mu 4 Q / pi).
    assert per_ball[0] == pytest.approx(0.069, abs=5e-4)
    assert per_ball[0] < per_ball[1] < 1.2e-3 * 4 * 100 / math.pi


def test_text_summary(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["model"]) == 0
    out = capsys.readouterr().out
    assert "beta = 0.347" in out and "a = 65.157 um" in out


def test_console_entry_point() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "gms_comp", "model", "--json"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert "sliding_force_N" in json.loads(result.stdout)["friction"]


def test_plot_writes_four_pngs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    figures: list[Figure] = []
    save = plots._save

    def keep(fig: Figure, path: Path) -> None:
        figures.append(fig)
        save(fig, path)

    monkeypatch.setattr(plots, "_save", keep)
    assert main(["model", "--json", "--plot", str(tmp_path / "figs")]) == 0
    captured = capsys.readouterr()
    json.loads(captured.out)  # stdout stays one JSON object
    assert captured.err.count("wrote ") == 4  # each file announced, on stderr under --json
    # A person can read them: a title on every figure, every axis labelled with its unit.
    assert len(figures) == 4
    for fig in figures:
        suptitle = fig.get_suptitle()
        plot_axes = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]
        for ax in plot_axes:
            assert suptitle or ax.get_title(), f"untitled figure {fig}"
            assert "[" in ax.get_xlabel() and "]" in ax.get_xlabel(), ax.get_xlabel()
            if ax.get_ylabel():  # shared y axes label the first plot only
                assert "[" in ax.get_ylabel() and "]" in ax.get_ylabel(), ax.get_ylabel()
        assert plot_axes[0].get_ylabel()
    names = sorted(p.name for p in (tmp_path / "figs").iterdir())
    assert names == [
        "fig3_stick_slip.png",
        "fig4_fields.png",
        "fig5_torque_map.png",
        "fig8_hysteresis.png",
    ]
    for name in names:
        assert (tmp_path / "figs" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_plot_dir_that_is_a_file_is_refused_at_parsing(tmp_path: Path) -> None:
    (tmp_path / "f").write_text("")
    assert main(["model", "--plot", str(tmp_path / "f")]) == 2


@pytest.mark.parametrize("elements", ["0", "1025", "-3", "many"])
def test_table_elements_bounded_at_parsing(elements: str, tmp_path: Path) -> None:
    """Refused before any fitting, like the config's [table] elements in [1, 1024]."""
    start = time.perf_counter()
    assert main(["table", "-o", str(tmp_path / "t.json"), "--elements", elements]) == 2
    assert time.perf_counter() - start < 10  # no reduction ran
    assert not (tmp_path / "t.json").exists()


def test_table_output_into_missing_folder_refused_at_parsing(tmp_path: Path) -> None:
    assert main(["table", "-o", str(tmp_path / "missing" / "t.json")]) == 2


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _interrupt(
    args: list[str], delay_s: float, after: str | None = None
) -> subprocess.CompletedProcess[str]:
    """Run ``python -m gms_comp ARGS``; send SIGINT ``delay_s`` after the interpreter is up
    (before that no Python program can handle it), or after it wrote a stderr line that
    starts with ``after``."""
    code = (
        "import sys, runpy; sys.stderr.write('ready\\n'); sys.stderr.flush(); "
        f"sys.argv = ['gms-comp', *{args!r}]; runpy.run_module('gms_comp', run_name='__main__')"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
        # As from a terminal: a background job (CI, `cmd &`) inherits SIGINT ignored.
        preexec_fn=_default_sigint,
    )
    assert proc.stderr is not None
    assert proc.stderr.readline() == "ready\n"
    said = ""
    if after is not None:  # the run has begun: its own message (on a fast machine the
        said = proc.stderr.readline()  # whole bench can be over in 6 s)
        assert said.startswith(after), said
    time.sleep(delay_s)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, said + err)


_LOST = """
import signal, sys, time
from gms_comp.app.cli import deliver_lost_interrupts
if sys.argv[1] == "hooked":
    deliver_lost_interrupts()
class Freed:
    def __del__(self):  # Ctrl-C while a finalizer runs: its KeyboardInterrupt is dropped
        signal.raise_signal(signal.SIGINT)
Freed()
for _ in range(200):  # 2 s, checking for signals every 10 ms
    time.sleep(0.01)
print("finished")
"""


@pytest.mark.parametrize("hooked", [True, False])
def test_ctrl_c_lost_in_a_finalizer_still_interrupts(hooked: bool) -> None:
    run = subprocess.run(
        [sys.executable, "-c", _LOST, "hooked" if hooked else "plain"],
        capture_output=True, text=True, timeout=120, cwd=ROOT, preexec_fn=_default_sigint,
    )  # fmt: skip
    if hooked:  # delivered again, uncaught: the process ends by SIGINT
        assert "Exception ignored" not in run.stderr, run.stderr
        assert run.returncode == -signal.SIGINT and "finished" not in run.stdout, run.stderr
    else:  # what the hook is for: without it the interrupt is reported and lost
        assert "Exception ignored in" in run.stderr and "KeyboardInterrupt" in run.stderr
        assert run.returncode == 0 and "finished" in run.stdout


def test_main_delivers_lost_interrupts_only_while_it_runs() -> None:
    assert main(["config", "--markdown"]) == 0
    assert getattr(sys.unraisablehook, "redelivers_interrupts", False)
    assert cli._REDELIVERY == {"armed": False, "lost": False}


@pytest.mark.parametrize(
    ("delay_s", "after"),
    [(1.0, None), (0.3, "measuring")],
    ids=["while-importing", "while-running"],
)
def test_ctrl_c_is_one_line_and_exit_130(delay_s: float, after: str | None) -> None:
    """Ctrl-C during the imports (numpy, numba: seconds) or the run: exit 130, one line."""
    result = _interrupt(["bench"], delay_s, after)  # the full bench runs for 5-30 s
    assert result.returncode == 130, result.stderr
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    # Before the arguments are parsed the CLI does not know the subcommand yet; once
    # running, bench has said on stderr what it measures.
    assert lines[-1] in ("gms-comp: interrupted", "gms-comp bench: interrupted"), lines
    assert all(line.startswith("measuring") for line in lines[:-1]), lines


def test_ctrl_c_inside_a_constructor_leaves_no_finalizer_traceback() -> None:
    """Ctrl-C inside a constructor (llvmlite's, while numba compiles) leaves a half-built
    object whose ``__del__`` fails when it is collected: still one line, no traceback."""
    code = """
import sys
import gms_comp.app.commands.model as model
from gms_comp.app.cli import main
class HalfBuilt:
    def __init__(self) -> None:
        raise KeyboardInterrupt  # before the attribute __del__ needs is set
    def __del__(self) -> None:
        self.handle.close()
def run(args):
    HalfBuilt()
model.run = run
sys.exit(main(["model"]))
"""
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120
    )
    assert result.returncode == 130, result.stderr
    assert result.stderr == "gms-comp model: interrupted\n"


def test_closed_stdout_is_quiet() -> None:
    """``gms-comp ... | head``: the reader going away is no traceback."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "gms_comp", "config", "--markdown"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()  # before the command writes anything
    err = proc.stderr.read()
    assert proc.wait(timeout=120) == 1
    assert "Traceback" not in err and "BrokenPipe" not in err, err


def test_bench_json_is_stdout_only(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "--quick", "--json"]) == 0
    captured = capsys.readouterr()
    data = json.loads(captured.out)["gms"]
    assert data["batch_samples_per_s"] > 0 and data["elements"] == 16
    assert captured.err.startswith("measuring")  # progress on stderr


def test_a_subcommand_loads_its_own_module_only() -> None:
    """``gms-comp diagnose`` does not import the simulator, the CAN stack or the other
    commands (the whole set costs a second more at every start); the bare ``--help``
    still lists every command."""
    probe = (
        "import sys\nfrom gms_comp.app.cli import main\n"
        "try:\n    main(['diagnose', '--help'])\nexcept SystemExit:\n    pass\n"
        "print([m for m in ('sim.plant', 'firmware_bridge.settings', "
        "'gms_comp.app.commands.simulate', 'gms_comp.app.commands.config') if m in sys.modules])"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, cwd=ROOT)
    assert done.stdout.strip().splitlines()[-1] == "[]", done.stdout
    top = subprocess.run(
        [sys.executable, "-m", "gms_comp", "--help"], capture_output=True, text=True, cwd=ROOT
    )
    for name in ("model", "config", "diagnose", "demo-trace", "simulate", "replay", "bench"):
        assert name in top.stdout


def test_an_interrupt_wrapped_by_set_name_is_an_interrupt(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # Python wraps an exception raised in __set_name__ (a dataclass created while a
    # command's module is imported) in a RuntimeError: Ctrl-C there gave a traceback
    def interrupted(_: object) -> None:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as err:
            raise RuntimeError("Error calling __set_name__") from err

    monkeypatch.setattr(cli, "build_parser", interrupted)
    assert main(["model"]) == 130
    assert capsys.readouterr().err.strip() == "gms-comp: interrupted"

    def broken(_: object) -> None:
        raise RuntimeError("not an interrupt")

    monkeypatch.setattr(cli, "build_parser", broken)
    with pytest.raises(RuntimeError, match="not an interrupt"):
        main(["model"])
