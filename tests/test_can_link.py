"""CanFeedforwardLink: the FeedforwardLink protocol over CAN, against the direct path."""

from __future__ import annotations

import math

import pytest

from firmware_bridge.faults import parse_fault
from firmware_bridge.link import CanFeedforwardLink
from firmware_bridge.settings import CanConfig

QUANTUM_A = {"cia402": 2.0 / 1000, "e2e": 1e-4}  # per mille of 2 A rated; 0.1 mA DBC scale


def currents(n: int) -> list[float]:
    return [0.8 * math.sin(2 * math.pi * 3 * k * 1e-3) for k in range(n)]


@pytest.mark.parametrize("profile", ["cia402", "e2e"])
def test_link_equals_direct_path_within_quantisation(profile: str) -> None:
    wanted = currents(300)
    with CanFeedforwardLink(profile=profile) as link:
        applied = [link.transfer(k, i) for k, i in enumerate(wanted)]
    # the link connected before the first transfer: every value applied in its own cycle
    err = max(abs(a - w) for a, w in zip(applied, wanted, strict=True))
    assert err <= QUANTUM_A[profile] / 2 + 1e-12


def test_link_satisfies_the_sim_protocol() -> None:
    from sim.link import FeedforwardLink

    with CanFeedforwardLink() as link:
        typed: FeedforwardLink = link  # structural: checked by mypy
        # connected on entry: cia402 applies each frame in its own cycle, 0.1 A
        # within half a quantum
        assert typed.transfer(0, 0.1) == pytest.approx(0.1, abs=QUANTUM_A["cia402"] / 2)


def test_faster_servo_loop_gets_a_frame_per_can_cycle_and_holds_between() -> None:
    cfg = CanConfig(cycle_period_s=1e-3)
    with CanFeedforwardLink(cfg, servo_period_s=2.5e-4) as link:
        applied = [link.transfer(k, 0.01 * (k // 4) + 0.1) for k in range(16)]
        sent = link.report()["frames_sent"]
    assert sent == 1 + 4  # the connection's 0 A command, then one per CAN cycle
    assert applied == pytest.approx([0.1] * 4 + [0.11] * 4 + [0.12] * 4 + [0.13] * 4, abs=1e-3)


def test_links_side_by_side_do_not_hear_each_other() -> None:
    with CanFeedforwardLink() as a, CanFeedforwardLink() as b:
        for k in range(20):
            a.transfer(k, 0.2)
            b.transfer(k, -0.2)
        # 20 each, plus the 0 A command that ended each link's connection
        assert a.report()["frames_applied"] == b.report()["frames_applied"] == 21
        assert a.rig.drive.applied_current_A == pytest.approx(0.2)


def test_link_with_faults_stays_safe() -> None:
    with CanFeedforwardLink(profile="e2e", faults=[parse_fault("corrupt:0.3")], seed=3) as link:
        for k, i in enumerate(currents(200)):
            link.transfer(k, i)
        report = link.report()
    assert report["frames_rejected"]["corrupt"] == report["faults_injected"]["corrupt"] > 0
    assert report["stale_or_corrupt_applied"] == 0


def test_link_outside_with_block_is_an_error() -> None:
    with pytest.raises(RuntimeError, match="with"):
        CanFeedforwardLink().transfer(0, 0.0)
