"""Every fault kind at once (each at 0.3-0.5) plus stalls and bus-off, many seeds, both profiles.

Stepped on the virtual bus, so each run is exact and repeatable. Per run, against
independent references:

- nothing stale or corrupt is applied: every applied payload is one the streamer
  sent, at most ``max_frame_age_cycles`` cycles before (the audit);
- never above the current limit;
- fallback: without a fresh frame, the applied value is zero at the latest
  ``rx_timeout + ramp`` after the last one;
- recovery: once the faults end, the drive applies the sent value again within the
  explicit restart (a request, its grant seen in the drive's status, then a command:
  two cycles; three for a SYNC follower, whose frames wait for the next SYNC) and
  from then on.

The default suite runs a few seeds; the ``slow`` test runs 20 seeds per profile
(and the cia402 SYNC follower), and :func:`summary` gives the counts for a report.
"""

from __future__ import annotations

import itertools
import math
import random
from dataclasses import dataclass, replace
from typing import Any

import pytest

from firmware_bridge.faults import parse_fault
from firmware_bridge.realtime import run_stream
from firmware_bridge.session import Rig
from firmware_bridge.settings import CanConfig

CYCLES = 900
FAULTS_END_S = 0.6
_channels = itertools.count()
VARIANTS: dict[str, dict[str, Any]] = {
    "cia402": {"profile": "cia402"},
    "e2e": {"profile": "e2e"},
    "cia402_nc_sync": {"profile": "cia402", "sync_master": False},
}


def wave(k: int) -> float:
    """Above the 1 A limit at its peaks, different every cycle."""
    return 1.5 * math.sin(2 * math.pi * 7 * k * 1e-3) + 1e-3 * (k % 11)


def fault_specs(seed: int) -> list[str]:
    rng = random.Random(seed)
    frame_faults = [
        f"{kind}:{rng.uniform(0.3, 0.5):.3f}@0.05-{FAULTS_END_S}"
        for kind in ("drop", "delay", "duplicate", "reorder", "corrupt")
    ]
    stall_s = rng.uniform(0.1, 0.15)
    return [
        *frame_faults,
        f"stall@{stall_s:.3f}-{stall_s + rng.uniform(0.002, 0.04):.3f}",  # short and long
        "stall@0.4-0.402",
        f"bus_error:{rng.uniform(0.3, 0.5):.3f}@0.25-0.3",
    ]


@dataclass(frozen=True)
class Outcome:
    """What one combined-fault run showed."""

    stale_or_corrupt_applied: int
    max_applied_A: float
    fallback_s: float  # longest time a non-zero value stayed applied without a fresh frame
    fallback_limit_s: float
    recovery_cycles: int  # from the end of the faults to the first frame applied
    recovery_limit: int  # the restart's request, grant and first command
    tracks_after_recovery: bool
    rejected: int


def combined_run(variant: str, seed: int) -> Outcome:
    cfg = replace(
        CanConfig(),
        max_current_A=1.0,
        channel=f"test-combined-{next(_channels)}",
        **VARIANTS[variant],
    )
    with Rig(cfg, [parse_fault(s) for s in fault_specs(seed)], seed=seed) as rig:
        applied = [rig.step(k, wave(k)) for k in range(CYCLES)]
        report = rig.report()
        period = cfg.cycle_period_s
        fresh = sorted({round(t / period) for t, _ in rig.drive.applied_log})
    held, last = 0, None
    fresh_set = set(fresh)
    for k, value in enumerate(applied):
        last = k if k in fresh_set else last
        if last is not None and value != 0.0:
            held = max(held, k - last)
    end = round(FAULTS_END_S / period)
    first_after = next(k for k in fresh if k >= end)
    # a cia402 follower applies the frame of the cycle before
    lag = 0 if cfg.sync_master or cfg.profile != "cia402" else 1
    quantum = 2.0 / 1000 if cfg.profile == "cia402" else 1e-4
    tracks = all(
        abs(applied[k] - max(-1.0, min(1.0, wave(k - lag)))) <= quantum / 2 + 1e-9
        for k in range(first_after, CYCLES)
    )
    return Outcome(
        stale_or_corrupt_applied=report["stale_or_corrupt_applied"],
        max_applied_A=max(abs(a) for a in applied),
        fallback_s=(held + 1) * period,
        fallback_limit_s=cfg.fallback_time_s,
        recovery_cycles=first_after - end,
        recovery_limit=2 + lag,
        tracks_after_recovery=tracks,
        rejected=sum(report["frames_rejected"].values()),
    )


def assert_safe(outcome: Outcome) -> None:
    assert outcome.stale_or_corrupt_applied == 0
    assert outcome.max_applied_A <= 1.0 + 1e-12
    assert outcome.fallback_s <= outcome.fallback_limit_s + 1e-12
    assert outcome.recovery_cycles <= outcome.recovery_limit and outcome.tracks_after_recovery
    assert outcome.rejected > 100  # the faults really hit


@pytest.mark.parametrize("variant", list(VARIANTS))
@pytest.mark.parametrize("seed", range(3))
def test_combined_faults_few_seeds(variant: str, seed: int) -> None:
    assert_safe(combined_run(variant, seed))


@pytest.mark.slow
@pytest.mark.parametrize("variant", list(VARIANTS))
def test_combined_faults_20_seeds(variant: str) -> None:
    for seed in range(100, 120):
        assert_safe(combined_run(variant, seed))


@pytest.mark.slow
@pytest.mark.parametrize("variant", list(VARIANTS))
def test_combined_faults_in_real_time(variant: str) -> None:
    """The same faults on the wall clock, drive in its own thread: the audit finds nothing."""
    for seed in range(2):
        cfg = replace(
            CanConfig(),
            max_current_A=1.0,
            channel=f"test-combined-rt-{next(_channels)}",
            **VARIANTS[variant],
        )
        faults = [parse_fault(s) for s in fault_specs(seed)]
        report = run_stream(cfg, lambda t_s: wave(round(t_s * 1e3)), 0.8, faults, seed)
        assert report["stale_or_corrupt_applied"] == 0
        assert report["max_applied_current_A"] <= 1.0 + 1e-12
        assert sum(report["frames_rejected"].values()) > 50


def summary(seeds: range = range(100, 120)) -> dict[str, dict[str, float]]:
    """Counts over ``seeds`` per variant, for a report (``python -m tests.test_can_combined``)."""
    out = {}
    for variant in VARIANTS:
        runs = [combined_run(variant, s) for s in seeds]
        out[variant] = {
            "runs": len(runs),
            "stale_or_corrupt_applied": sum(r.stale_or_corrupt_applied for r in runs),
            "max_applied_A": max(r.max_applied_A for r in runs),
            "max_fallback_s": max(r.fallback_s for r in runs),
            "fallback_limit_s": runs[0].fallback_limit_s,
            "max_recovery_cycles": max(r.recovery_cycles for r in runs),
            "all_track_after_recovery": all(r.tracks_after_recovery for r in runs),
            "frames_rejected": sum(r.rejected for r in runs),
        }
    return out


if __name__ == "__main__":
    import json

    print(json.dumps(summary(), indent=2))
