"""Fault tolerance of the CAN feedforward, both profiles, stepped on the virtual bus.

Every run checks the safety invariants against independent references: what the
drive applied must be a payload the streamer actually sent in the last cycles
(stale_or_corrupt_applied == 0), never above the limit, zero within
rx_timeout + ramp after the link goes, and back to the sent value once it returns.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import can
import pytest

from firmware_bridge.faults import parse_fault
from firmware_bridge.session import Rig
from firmware_bridge.settings import CanConfig
from gms_comp.errors import BusError

PROFILES = ("cia402", "e2e")
CYCLES = 400
# The start (firmware_bridge.freshness): cycle 0 only tells the compensator the drive's
# cycle, cycle 1 carries its request for the session, granted at once; commands from 2.
FIRST_COMMAND = 2
_channels = itertools.count()


def config(profile: str) -> CanConfig:
    return replace(
        CanConfig(),
        profile=profile,
        max_current_A=1.0,
        channel=f"test-faults-{next(_channels)}",
    )


def wave(k: int) -> float:
    """Above the 1 A limit at its peaks, different every cycle."""
    return 1.5 * math.sin(2 * math.pi * 7 * k * 1e-3) + 1e-3 * (k % 11)


def run(profile: str, *specs: str, cycles: int = CYCLES) -> tuple[Rig, list[float]]:
    with Rig(config(profile), [parse_fault(s) for s in specs], seed=7) as rig:
        applied = [rig.step(k, wave(k)) for k in range(cycles)]
    return rig, applied


def assert_safe(rig: Rig, applied: list[float]) -> None:
    report = rig.report()
    assert report["stale_or_corrupt_applied"] == 0
    assert max(abs(a) for a in applied) <= rig.cfg.max_current_A + 1e-12


@pytest.mark.parametrize("profile", PROFILES)
def test_clean_link_applies_every_frame_quantised(profile: str) -> None:
    rig, applied = run(profile)
    report = rig.report()
    assert sum(report["frames_rejected"].values()) == 0
    first = FIRST_COMMAND
    assert report["frames_applied"] == CYCLES - first
    assert report["sessions_granted"] == 1
    step = 1e-4 if profile == "e2e" else 2.0 / 1000
    for k in range(first, CYCLES):
        assert applied[k] == pytest.approx(max(-1.0, min(1.0, wave(k))), abs=step / 2 + 1e-12)
    assert_safe(rig, applied)


@pytest.mark.parametrize("profile", PROFILES)
@pytest.mark.parametrize(
    ("spec", "reasons"),
    [
        ("duplicate:0.1@0-0.35", ("duplicate",)),
        ("corrupt:0.1@0-0.35", ("corrupt",)),
        # a cia402 frame is a cycle old when applied at its SYNC (the drive's status it is
        # dated by was sampled a tick before): one held a cycle more is stale by then
        ("reorder:0.1@0-0.35", ("out_of_order", "stale")),
        ("delay:0.1@0-0.35", ("out_of_order", "stale")),
        ("drop:0.2@0-0.35", ()),
    ],
)
def test_frame_faults_are_rejected_and_counted(
    profile: str, spec: str, reasons: tuple[str, ...]
) -> None:
    rig, applied = run(profile, spec)
    report = rig.report()
    kind = spec.split(":")[0]  # the fault ends before the run does: nothing still held
    injected = report["faults_injected"][kind]
    assert injected > 10
    assert_safe(rig, applied)
    if reasons:  # every damaged frame is rejected for one of the expected reasons
        assert sum(report["frames_rejected"][r] for r in reasons) >= injected
    if kind in ("duplicate", "corrupt"):
        assert sum(report["frames_rejected"].values()) == injected


@pytest.mark.parametrize("profile", PROFILES)
@pytest.mark.parametrize("spec", ["drop@0.1-0.2", "stall@0.1-0.2", "bus_error@0.1-0.2"])
def test_link_loss_falls_back_to_zero_in_time_and_recovers(profile: str, spec: str) -> None:
    rig, applied = run(profile, spec)
    cfg = rig.cfg
    lost, back = 100, 200  # cycles at 1 ms
    zero_by = lost + cfg.timeout_cycles + cfg.ramp_cycles  # rx_timeout + ramp after the last frame
    assert all(a == 0.0 for a in applied[zero_by:back])
    ramp_step_A = cfg.max_current_A / cfg.ramp_cycles
    assert all(
        abs(b - a) <= ramp_step_A + 1e-3
        for a, b in zip(applied[lost - 1 : zero_by], applied[lost:zero_by], strict=False)
    )
    recovered = back + 2  # e2e: one frame to resynchronise the counter
    for k in range(recovered, CYCLES):
        assert applied[k] == pytest.approx(max(-1.0, min(1.0, wave(k))), abs=1e-3)
    assert_safe(rig, applied)


def test_cia402_drive_sends_emcy_for_rpdo_timeout_and_lost_sync() -> None:
    rig, applied = run("cia402", "stall@0.1-0.3")
    emcy = rig.tx.emcy_received  # type: ignore[attr-defined]
    assert 0x8250 in emcy  # RPDO timeout (CiA 301)
    assert 0x8100 in emcy  # SYNC lost, from 1.5 x 0x1006
    assert 0x8130 in emcy  # compensator heartbeat lost (0x1016)
    assert_safe(rig, applied)


def test_e2e_drive_reports_status_back() -> None:
    rig, applied = run("e2e", cycles=20)
    status = rig.tx.last_status  # type: ignore[attr-defined]
    assert status is not None
    assert status.applied_current_A == pytest.approx(applied[-2], abs=1e-4)  # sent last cycle


@pytest.mark.parametrize("profile", PROFILES)
def test_stale_frame_after_loss_is_not_applied(profile: str) -> None:
    """Delays and drops together: a delayed frame arriving after its successor was lost."""
    rig, applied = run(profile, "delay:0.2", "drop:0.2")
    report = rig.report()
    # Both faults really happened, and late frames were turned away, not applied.
    assert report["faults_injected"]["delay"] > 10 and report["faults_injected"]["drop"] > 10
    late = ("out_of_order", "stale", "duplicate")
    assert sum(report["frames_rejected"][r] for r in late) > 0
    assert_safe(rig, applied)


def test_stream_falls_silent_when_the_loop_stops() -> None:
    """No background sender: without a call per cycle, nothing reaches the bus."""
    cfg = config("e2e")
    with Rig(cfg) as rig:
        for k in range(5):
            rig.step(k, 0.1)
        assert rig.drive.bus.recv(timeout=0.05) is None


def test_follower_mode_applies_one_cycle_later() -> None:
    cfg = replace(config("cia402"), sync_master=False)
    with Rig(cfg) as rig:
        applied = [rig.step(k, 0.002 * k) for k in range(10)]
    # each step of the handshake waits for the next SYNC as well: commands from cycle 3,
    # applied one cycle later
    start = FIRST_COMMAND + 1
    assert applied[: start + 1] == [0.0] * (start + 1)
    assert applied[start + 1 :] == pytest.approx([0.002 * (k - 1) for k in range(start + 1, 10)])


def test_faults_need_a_valid_spec() -> None:
    for bad in ("flood", "drop:2", "drop@0.3-0.1", "drop:x"):
        with pytest.raises(BusError, match="fault spec"):
            parse_fault(bad)


def test_injected_bus_error_surfaces_as_can_error_to_the_sender() -> None:
    with Rig(config("e2e"), [parse_fault("bus_error")]) as rig, pytest.raises(can.CanError):
        rig.faulty.send(can.Message(arbitration_id=0x120, data=bytes(8)))
