"""Diagnosis benchmarks; print JSON.

- ``seconds``: ``diagnose`` on a 100 000-sample measured-like trace (spec: < 30 s).
- ``hit_rate``: per hidden effect, the share of seeds where the blind diagnosis names it,
  recovers its main parameter within the tolerance of tests/test_diagnosis.py and has a
  positive gain.
- ``false_positive_rate``: the share of effect-free traces where anything is named.

``python benchmarks/bench_diagnose.py [SEEDS]`` (default 5 seeds per effect, 2x as many
effect-free traces).
"""

from __future__ import annotations

import json
import sys
import time

from gms_comp.commands.demo_trace import MAIN_PARAMETER, generate
from gms_comp.diagnosis.run import diagnose

# The relative tolerances the tests state (tests/test_diagnosis.py).
TOLERANCE = {
    "offset": 0.05, "viscous": 0.1, "position_ripple": 0.02, "inertia": 0.05,
    "sensor_lowpass": 0.25, "stribeck": 0.2, "reversal_transient": 0.2, "dwell_time": 0.25,
    "drift": 0.25,
}  # fmt: skip


def hit(hidden: str, seed: int) -> bool:
    g = generate(hidden, seed)
    result = diagnose(g.trace)
    if result.effect != hidden or g.hidden is None or result.gain <= 0:
        return False
    key = MAIN_PARAMETER[hidden]
    truth = g.hidden.parameters()[key]
    return abs(result.to_json()["parameters"][key] - truth) <= TOLERANCE[hidden] * abs(truth)


def main() -> None:
    n_seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    g = generate("position_ripple", 0, scale=2.75)  # >= 100 000 samples
    diagnose(generate("offset", 0).trace)  # numba compile outside the timing
    start = time.perf_counter()
    result = diagnose(g.trace)
    elapsed = time.perf_counter() - start
    seeds = range(100, 100 + n_seeds)
    hits = {name: sum(hit(name, s) for s in seeds) / n_seeds for name in MAIN_PARAMETER}
    clean = range(1000, 1000 + 2 * n_seeds)
    named = [s for s in clean if diagnose(generate("none", s).trace).effect != "none"]
    print(json.dumps({
        "samples": len(g.trace), "seconds": round(elapsed, 2), "effect": result.effect,
        "gain": round(result.gain, 3), "seeds_per_effect": n_seeds, "hit_rate": hits,
        "false_positive_rate": len(named) / len(clean), "false_positive_seeds": named,
    }))  # fmt: skip


if __name__ == "__main__":
    main()
