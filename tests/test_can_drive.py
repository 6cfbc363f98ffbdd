"""The cia402 drive emulator as a CANopen device: SDO, its heartbeat, following the NC's SYNC."""

from __future__ import annotations

import configparser
import itertools
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace

import can
import canopen
import pytest

from firmware_bridge import realtime as session
from firmware_bridge.emulator import DriveEmulator
from firmware_bridge.profiles.cia402.codec import default_eds_path
from firmware_bridge.profiles.cia402.drive import Cia402Drive
from firmware_bridge.realtime import run_stream
from firmware_bridge.session import Rig
from firmware_bridge.settings import CanConfig

_channels = itertools.count()


def config(**changes: object) -> CanConfig:
    return replace(CanConfig(), channel=f"test-drive-{next(_channels)}", **changes)  # type: ignore[arg-type]


def eds_default(index: int) -> int:
    """An object's default read straight from the EDS text, not through canopen."""
    eds = configparser.ConfigParser()
    eds.read(default_eds_path())
    return int(eds[f"{index:04X}"]["DefaultValue"], 0)


@contextmanager
def running_drive(cfg: CanConfig) -> Iterator[tuple[DriveEmulator, canopen.RemoteNode]]:
    """The emulator running in a thread, and an SDO client (an NC) on the same bus."""
    stop = threading.Event()
    with can.Bus(interface="virtual", channel=cfg.channel) as drive_bus:
        drive = DriveEmulator(cfg, drive_bus)
        thread = threading.Thread(target=drive.run, args=(stop,))
        network = canopen.Network()
        # canopen's notifier polls the bus every second by default: disconnecting
        # would wait up to that long for its reader thread.
        network.NOTIFIER_CYCLE = 0.05
        network.connect(interface="virtual", channel=cfg.channel)
        try:
            node = canopen.RemoteNode(cfg.drive_node_id, str(default_eds_path()))
            network.add_node(node)
            thread.start()
            yield drive, node
        finally:
            stop.set()
            if thread.is_alive():
                thread.join()
            network.disconnect()


def test_nc_reads_and_writes_drive_objects_by_sdo() -> None:
    with running_drive(config()) as (drive, node):
        assert node.sdo[0x6076].raw == eds_default(0x6076)  # rated torque (force), as shipped
        assert node.sdo[0x6075].raw == 2000  # rated current 2 A in mA, set from [can]
        assert isinstance(drive.side, Cia402Drive)
        for code, action in ((1, "fault"), (2, "disable_voltage"), (0, "no_action")):
            node.sdo[0x6007].raw = code
            assert node.sdo[0x6007].raw == code
            assert drive.side.receiver.abort_action == action


def test_drive_heartbeat_stops_when_0x1017_is_zeroed() -> None:
    with running_drive(config()) as (drive, node):
        assert node.sdo[0x1017].raw == 100  # [can] heartbeat_period_s = 0.1 s
        node.sdo[0x1017].raw = 0
    # The thread has stopped: step the drive on a clock of its own for 1 s (ten
    # heartbeat periods) rather than sleep and hope the thread was scheduled. The
    # bus is closed too, so a heartbeat would also raise on sending.
    assert isinstance(drive.side, Cia402Drive)
    receiver = drive.side.receiver
    sent = receiver.heartbeats_sent
    assert sent >= 1  # it did beat before 0x1017 was zeroed
    start_s = time.time()
    for k in range(1000):
        drive.tick(start_s + k * drive.cfg.cycle_period_s)
    assert receiver.heartbeats_sent == sent


def test_drive_heartbeat_period_follows_0x1017() -> None:
    """Stepped 1 s at 1 ms: heartbeats at 0, 0.1, ..., 0.9 s, received by the compensator."""
    with Rig(config(heartbeat_period_s=0.1)) as rig:
        for k in range(1000):
            rig.step(k, 0.0)
        rig.streamer.drain_replies()
    assert rig.tx.drive_heartbeats == 10  # type: ignore[attr-defined]


def test_real_time_stream_follows_the_nc_sync() -> None:
    cfg = config(sync_master=False, max_current_A=1.0)
    report = run_stream(cfg, lambda t_s: 2.0 * t_s, duration_s=0.3)  # ramps past the limit
    assert report["sync_source"] == "nc" and not report["sync_lost"]
    assert report["syncs_seen"] >= report["frames_sent"] > 0  # one RPDO per SYNC at most
    assert report["stale_or_corrupt_applied"] == 0
    assert report["max_applied_current_A"] <= cfg.max_current_A
    assert report["frames_applied"] > report["frames_sent"] // 2


def test_follower_without_sync_stays_silent(monkeypatch: pytest.MonkeyPatch) -> None:
    """No NC SYNC on the bus: the follower sends nothing, the drive applies nothing."""
    # The outcome does not depend on how long the follower waits: 0.2 s, not the 2 s default.
    monkeypatch.setattr(session, "FIRST_SYNC_WAIT_S", 0.2)
    cfg = config(sync_master=False)
    with Rig(cfg, builtin_drive=False) as rig:
        assert rig.nc_sync is None
    report = run_stream(cfg, lambda t_s: 0.5, duration_s=0.05, builtin_drive=False)
    assert report["sync_lost"] and report["frames_sent"] == 0


@pytest.mark.parametrize("profile", ["cia402", "e2e"])
def test_external_drive_leaves_drive_figures_null(profile: str) -> None:
    """No drive answers on the channel: no clock to date frames by, so nothing is sent."""
    report = run_stream(config(profile=profile), lambda t_s: 0.1, 0.05, builtin_drive=False)
    assert report["drive"] == "external" and report["frames_applied"] is None
    assert report["frames_sent"] == report["requests_sent"] == 0
    assert report["undated_cycles"] > 0
