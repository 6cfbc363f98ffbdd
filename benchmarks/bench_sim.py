"""Speed and compensation figures of the simulated axis; prints one JSON object.

- ``closed_loop``: real-time factor of the closed loop alone (reference, truth,
  table and calibration built beforehand) with the ball-model truth at the
  servo rate, per strategy, best of ``--repeats``. This is the simulator's own
  run (:func:`sim.closed_loop.run`, one compiled call per run on the direct
  path), the code the tests and ``gms-comp simulate`` use.
- ``default``: the default scenario's scores and the GMS ratios of the targets.
- ``friction_level_misset``: the GMS table mis-set by -20 % / +20 % against the
  correctly calibrated Coulomb+viscous (and with every model mis-set alike).
- ``coulomb_band``: Coulomb+viscous with wider velocity bands (a drive engineer's
  tuning), to show how much of the gap to GMS a tuned band closes.

Usage: ``python benchmarks/bench_sim.py [CONFIG] [--repeats N]``
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import time
from typing import Any

from sim.link import DirectLink
from sim.scenarios import (
    Loop,
    Physics,
    Scenario,
    build_observer,
    build_reference,
    load_scenario,
    run_strategies,
    score,
)
from sim.strategies import STRATEGIES


def closed_loop_speed(s: Scenario, repeats: int) -> dict[str, float]:
    """Real-time factor of the closed loop alone, per strategy (best of ``repeats``)."""
    physics = Physics()
    loop = Loop.build(s, physics)
    factors = {}
    for name in STRATEGIES:
        observer = build_observer(s, name, physics)
        best_s = math.inf
        for _ in range(repeats):
            started = time.perf_counter()
            loop.run(observer, DirectLink(s.scenario.transport_delay_cycles))
            best_s = min(best_s, time.perf_counter() - started)
        factors[name] = loop.reference.duration_s / best_s
    return factors


def peaks(s: Scenario, strategies: tuple[str, ...] = STRATEGIES) -> dict[str, float | None]:
    """Peak reversal error per strategy."""
    results = run_strategies(s, strategies)
    return {name: score(r, s.scenario)["peak_reversal_error_m"] for name, r in results.items()}


def with_compensator(s: Scenario, **changes: Any) -> Scenario:
    return dataclasses.replace(s, compensator=dataclasses.replace(s.compensator, **changes))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("config", nargs="?", help="config TOML (default: Table 1)")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    s = load_scenario(args.config)
    run_strategies(s, ("gms",))  # compile / load numba caches before timing
    speed = closed_loop_speed(s, args.repeats)
    scores = {name: score(r, s.scenario) for name, r in run_strategies(s).items()}
    misset = {}
    for scale in (0.8, 1.2):
        alone = peaks(with_compensator(s, friction_level_scale=scale), ("gms",))["gms"]
        everyone = peaks(with_compensator(s, friction_level_scale=scale))
        misset[f"{scale:g}"] = {"gms_alone_misset_m": alone, "all_misset_m": everyone}
    bands = {
        f"{band:g}": peaks(
            with_compensator(s, coulomb_velocity_band_m_s=band), ("coulomb_viscous",)
        )["coulomb_viscous"]
        for band in (1e-3, 2e-3, 5e-3)
    }
    peak = {name: sc["peak_reversal_error_m"] or math.nan for name, sc in scores.items()}
    report = {
        "config": s.path,
        "servo_rate_Hz": s.controller.servo_rate_Hz,
        "duration_s": build_reference(s).duration_s,
        "closed_loop_realtime_factor": speed,
        "default": {
            "scores": scores,
            "gms_reduction_vs_none": peak["none"] / peak["gms"],
            "gms_reduction_vs_coulomb_viscous": peak["coulomb_viscous"] / peak["gms"],
        },
        "friction_level_misset": misset,
        "coulomb_band_peak_reversal_error_m": bands,
    }
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
