"""Benchmark of the physics layer; prints one JSON object.

Rolling-line search with the steady field, the transient model over the
seed's Fig. 7 profile (2 mm of travel, four balls), the streaming step rate
(4 kHz closed loop at 20x real time needs >= 80 000 steps/s), and run time
and results against the grid resolution of the transient model.

    python benchmarks/bench_physics.py
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable
from functools import partial
from typing import Any

import numpy as np

from gms_comp.physics import ball_model
from gms_comp.physics.config import BallConfig, load_ball_config
from gms_comp.physics.profiles import seed_fig7_profile
from gms_comp.physics.transient import BallSetFriction


def best_of(fn: Callable[[], Any], repeat: int = 3) -> tuple[float, Any]:
    """Shortest wall time of ``repeat`` runs and the last result."""
    times, result = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return min(times), result


def with_grid(cfg: BallConfig, stripes: int, bristles: int) -> BallConfig:
    model = dataclasses.replace(cfg.model, stripes_per_area=stripes, bristles_per_stripe=bristles)
    return dataclasses.replace(cfg, model=model)


def rolling_line_search(cfg: BallConfig) -> dict[str, Any]:
    def search() -> ball_model.SteadyResult:
        ball_model.steady_state.cache_clear()
        return ball_model.steady_state(cfg, cfg.stand.ball_loads_N[0])

    seconds, result = best_of(search)
    return {
        "seconds": seconds,
        "lambda_count": len(result.lambdas),
        "beta": result.beta,
        "sliding_force_N": ball_model.sliding_force_N(cfg),
    }


def fig7_transient(cfg: BallConfig) -> dict[str, Any]:
    friction = BallSetFriction(cfg)
    _, x, v = seed_fig7_profile(sample_rate_Hz=10_000.0)
    friction.force(x[:10], v[:10])  # compile / load the numba cache
    seconds, force = best_of(lambda: friction.force(x, v))
    setup, _ = best_of(lambda: BallSetFriction(cfg), repeat=1)
    return {
        "seconds": seconds,
        "setup_seconds": setup,
        "samples": int(x.size),
        "travel_m": float(np.sum(np.abs(np.diff(x)))),
        "max_force_N": float(force.max()),
    }


def streaming(cfg: BallConfig, steps: int = 100_000) -> dict[str, Any]:
    friction = BallSetFriction(cfg)
    t = np.arange(steps) / 4000.0
    x = 1e-3 * np.sin(2 * np.pi * 2.0 * t)
    v = 1e-3 * 2 * np.pi * 2.0 * np.cos(2 * np.pi * 2.0 * t)
    friction.step(0.0, 0.0)

    def run() -> None:
        friction.reset()
        for p, s in zip(x.tolist(), v.tolist(), strict=True):
            friction.step(p, s)

    seconds, _ = best_of(run, repeat=2)
    rate = steps / seconds
    return {"steps_per_s": rate, "real_time_factor_at_4kHz": rate / 4000.0}


def grid_study(cfg: BallConfig) -> list[dict[str, Any]]:
    """Fig. 7 run time and results for growing grids, against the finest grid."""
    _, x, v = seed_fig7_profile(sample_rate_Hz=10_000.0)
    grids = [(2, 8), (4, 16), (6, 24), (8, 32), (12, 48), (16, 64), (24, 96), (32, 128)]
    runs = []
    for stripes, bristles in grids:
        friction = BallSetFriction(with_grid(cfg, stripes, bristles))
        friction.force(x[:10], v[:10])
        seconds, force = best_of(partial(friction.force, x, v), repeat=1)
        runs.append((stripes, bristles, seconds, force))
    reference = runs[-1][3]
    steady = ball_model.sliding_force_N(cfg)
    moving = v != 0
    rows = []
    for stripes, bristles, seconds, force in runs:
        tail = force[(v > 0) & (x > 0.5e-3)]
        rows.append(
            {
                "stripes_per_area": stripes,
                "bristles_per_stripe": bristles,
                "bristles_per_half_contact": 4 * stripes * bristles,  # four areas of Eq. 14
                "fig7_seconds": seconds,
                "steady_error_rel": float(tail.mean() / steady - 1.0),
                "steady_ripple_rel": float(np.ptp(tail) / steady),
                "fig7_mean_abs_diff_vs_finest_rel": float(
                    np.mean(np.abs(force[moving] - reference[moving])) / steady
                ),
            }
        )
    return rows


def main() -> None:
    cfg = load_ball_config()
    report = {
        "note": "wall-clock on a shared 2-core machine; best of repeats",
        "grid": {
            "stripes_per_area": cfg.model.stripes_per_area,
            "bristles_per_stripe": cfg.model.bristles_per_stripe,
        },
        "rolling_line_search": rolling_line_search(cfg),
        "fig7_transient": fig7_transient(cfg),
        "streaming": streaming(cfg),
        "grid_study": grid_study(cfg),
    }
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
