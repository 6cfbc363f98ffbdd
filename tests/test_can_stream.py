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

from firmware_bridge.session import run_stream
from firmware_bridge.settings import CanConfig
from gms_comp.cli import main
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
            "--json",
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
    assert {0x201, 0x80} <= ids  # RPDO1 of node 1 and SYNC


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
    assert "another node" in err and err.count("\n") == 1
    assert reports[0]["stale_or_corrupt_applied"] == 0  # the first one was not disturbed
