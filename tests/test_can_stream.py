"""gms-comp stream: short real-time runs on the virtual bus (no timing asserted)."""

from __future__ import annotations

import json
import threading
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import can
import pytest

from firmware_bridge.realtime import run_stream
from firmware_bridge.settings import CanConfig
from gms_comp.app.cli import main
from gms_comp.config import default_config_path

KEYS = {
    "frames_sent",
    "frames_applied",
    "frames_rejected",
    "stale_or_corrupt_applied",
    "late_cycles",
    "max_lateness_s",
    "loop_time_p99_s",
    "bus_load",
    "max_applied_current_A",
}


def stream(tmp_path: Path, *args: str) -> tuple[int, dict[str, Any]]:
    out = tmp_path / "report.json"
    code = main(
        [
            "stream",
            "--duration",
            "0.2",
            "--channel",
            f"cli-{tmp_path.name}",
            "-o",
            str(out),
            *args,
        ]
    )
    return code, json.loads(out.read_text())


@pytest.mark.parametrize("profile", ["cia402", "e2e"])
def test_stream_reports_all_keys_and_applies_nothing_unsafe(tmp_path: Path, profile: str) -> None:
    code, report = stream(tmp_path, "--profile", profile)
    assert code == 0
    assert report.keys() >= KEYS
    assert report["stale_or_corrupt_applied"] == 0
    assert report["bus_load"] < 0.7
    assert isinstance(report["frames_applied"], int) and report["frames_applied"] > 0


def test_stream_with_faults_counts_rejections(tmp_path: Path) -> None:
    code, report = stream(
        tmp_path,
        "--profile",
        "e2e",
        "--fault",
        "corrupt:0.2",
        "--fault",
        "duplicate:0.1",
        "--fault",
        "stall@0.05-0.08",
    )
    assert code == 0
    rejected = report["frames_rejected"]
    assert isinstance(rejected, dict) and rejected["corrupt"] > 0 and rejected["duplicate"] > 0
    assert report["stale_or_corrupt_applied"] == 0


def test_stream_logs_frames_to_blf(tmp_path: Path) -> None:
    log = tmp_path / "frames.blf"
    code, _ = stream(tmp_path, "--log", str(log))
    assert code == 0
    with can.BLFReader(str(log)) as reader:
        ids = {msg.arbitration_id for msg in reader}
    assert {0x301, 0x80, 0x181} <= ids  # RPDO2 of node 1, SYNC, the drive's TPDO1


def test_bad_fault_spec_is_one_line_and_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["stream", "--duration", "0.1", "--fault", "meteor"]) == 2
    err = capsys.readouterr().err
    assert "fault spec" in err and err.count("\n") == 1


def test_bus_load_over_70_percent_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cfg = tmp_path / "fast.toml"  # 2 frames x 5 kHz x 135 bit = 135 % of 1 Mbit/s
    cfg.write_text(
        default_config_path().read_text() + "\n[can]\nprofile = 'e2e'\ncycle_period_s = 2e-4\n"
    )
    assert main(["stream", str(cfg), "--duration", "0.1"]) == 2
    assert "bus load" in capsys.readouterr().err


@pytest.mark.parametrize("profile", ["cia402", "e2e"])
def test_second_compensator_on_the_channel_is_refused(
    tmp_path: Path, profile: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """One compensator per drive: a stream already running on the channel is detected."""
    channel = f"cli-dup-{profile}-{tmp_path.name}"
    first = replace(CanConfig(), profile=profile, channel=channel)
    reports: list[dict[str, Any]] = []
    other = threading.Thread(
        target=lambda: reports.append(run_stream(first, lambda t_s: 0.1, duration_s=1.0))
    )
    other.start()
    try:
        time.sleep(0.3)  # the first stream is running
        code = main(["stream", "--profile", profile, "--channel", channel, "--duration", "0.1"])
    finally:
        other.join()
    err = capsys.readouterr().err
    assert code == 2
    assert "one compensator per drive" in err and err.count("\n") == 1
    assert reports[0]["stale_or_corrupt_applied"] == 0  # the first one was not disturbed


@pytest.mark.parametrize("profile", ["cia402", "e2e"])
def test_json_flag_prints_only_json_and_a_clean_stop_raises_no_fault(
    tmp_path: Path, profile: str, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "r.json"
    args = ["stream", "--profile", profile, "--channel", f"cli-json-{profile}-{tmp_path.name}"]
    code = main([*args, "--duration", "0.2", "--json", "-o", str(out)])
    captured = capsys.readouterr()
    report = json.loads(captured.out)  # stdout is the JSON and nothing else
    assert code == 0 and report == json.loads(out.read_text())
    assert f"wrote {out}" in captured.err
    # the stream ends in order: the drive is not left faulted by the end of the stream
    assert report["drive_state"] == ("pre_operational" if profile == "cia402" else "waiting")
    assert report["end_of_stream"].startswith("ramped to 0 A")


def test_summary_on_stdout_says_how_the_stream_ended(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["stream", "--channel", f"cli-sum-{tmp_path.name}", "--duration", "0.1"])
    text = capsys.readouterr().out
    assert code == 0
    assert "streamed" in text and "stale or corrupt applied: 0" in text
    assert "end: ramped to 0 A; session released, NMT pre-operational" in text
    assert "drive state at the end: pre_operational" in text


@pytest.mark.parametrize("duration", ["0", "-1", "nan", "3601", "1e7"])
def test_duration_out_of_bounds_is_one_line_and_exit_2(
    duration: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["stream", "--duration", duration]) == 2
    err = capsys.readouterr().err
    assert "--duration" in err and err.count("\n") == 1


def test_too_many_cycles_are_refused_before_streaming(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cfg = tmp_path / "fast.toml"  # 1 h at 0.5 ms: 7.2 million cycles
    cfg.write_text(default_config_path().read_text() + "\n[can]\ncycle_period_s = 5e-4\n")
    assert main(["stream", str(cfg), "--duration", "3600"]) == 2
    err = capsys.readouterr().err
    assert "cycles" in err and err.count("\n") == 1


def test_cycle_below_100_us_is_refused_in_the_config(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cfg = tmp_path / "tiny.toml"
    cfg.write_text(default_config_path().read_text() + "\n[can]\ncycle_period_s = 1e-9\n")
    assert main(["stream", str(cfg), "--duration", "0.1"]) == 2
    err = capsys.readouterr().err
    assert "can.cycle_period_s" in err and err.count("\n") == 1


def test_missing_socketcan_channel_says_how_to_create_a_vcan(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code = main(["stream", "--interface", "socketcan", "--channel", "gmsnone0", "--duration", "1"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "ip link add dev gmsnone0 type vcan && ip link set up gmsnone0" in err


def test_output_folder_is_checked_before_streaming(tmp_path: Path) -> None:
    assert main(["stream", "-o", str(tmp_path / "missing" / "r.json")]) == 2


def test_the_claim_holds_while_the_compensator_sets_up() -> None:
    """A frame with this compensator's id during its set-up ends it before it streams."""
    from firmware_bridge.session import Rig
    from firmware_bridge.streamer import ChannelTakenError

    cfg = replace(CanConfig(), profile="e2e", channel=f"claim-setup-{time.monotonic_ns()}")
    with Rig(cfg) as rig, can.Bus(interface="virtual", channel=cfg.channel) as other:
        taken = pytest.raises(ChannelTakenError, match="one compensator per drive")
        with taken, rig.watching():
            time.sleep(0.05)  # the observer's tables and compilation
            other.send(can.Message(arbitration_id=0x120, data=bytes(8), is_extended_id=False))
            time.sleep(0.05)
        assert rig.streamer.frames_sent == 0


@pytest.mark.slow
@pytest.mark.parametrize(("signame", "code"), [("SIGINT", 130), ("SIGTERM", 143)])
def test_a_signal_while_streaming_is_a_clean_stop(tmp_path: Path, signame: str, code: int) -> None:
    """Ctrl-C or SIGTERM once frames flow: ramp to 0 A, session released, NMT, no EMCY."""
    import signal
    import subprocess
    import sys

    out = tmp_path / "report.json"
    proc = subprocess.Popen(
        [sys.executable, "-m", "gms_comp", "stream", "--channel", f"sig-{tmp_path.name}",
         "--duration", "30", "-o", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    assert proc.stderr is not None
    for line in proc.stderr:  # wait for frames to flow (progress lines come each second)
        if line.startswith("stream: 1 s"):
            break
    proc.send_signal(getattr(signal, signame))
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code
    assert f"stopped by {signame}" in err and "Traceback" not in err
    report = json.loads(out.read_text())
    assert report["interrupted"] and report["drive_state"] == "pre_operational"
    assert report["emcy"] == [] or set(report["emcy"]) <= {"0x8100", "0x8250", "0x8130"}
    assert report["stale_or_corrupt_applied"] == 0
