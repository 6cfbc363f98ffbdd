"""``gms-comp bench``: speed of the GMS kernel (batch, streaming) against scipy's solve_ivp.

The figures are wall-clock on this machine; benchmarks/bench_gms.py runs the same
measurement as a script.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from gms_comp.arrays import FloatArray
from gms_comp.gms import GmsParams, GmsStream, simulate

SAMPLE_RATE_Hz = 10_000.0


def full_model(n_elements: int) -> GmsParams:
    """N elements with every feature on: velocity level, finite attraction, viscous term."""
    breakpoints = np.geomspace(1e-7, 1e-4, n_elements)
    k = np.full(n_elements, 0.28 / 1.2 / n_elements) / breakpoints
    return GmsParams(
        k,
        k * breakpoints,
        slip_level=1.2,
        transition_velocity_m_s=1e-4,
        attraction_rate_per_s=2e4,
        viscous_Ns_per_m=0.5,
    )


def trajectory(samples: int) -> tuple[FloatArray, FloatArray]:
    """A large slow sine with a small fast one on top: reversals of many amplitudes."""
    t = np.arange(samples) / SAMPLE_RATE_Hz
    w1, w2 = 2 * np.pi * 0.5, 2 * np.pi * 37.0
    x = 1e-3 * np.sin(w1 * t) + 1e-5 * np.sin(w2 * t)
    v = 1e-3 * w1 * np.cos(w1 * t) + 1e-5 * w2 * np.cos(w2 * t)
    return x, v


def _best_seconds(fn: Callable[[], object], repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return float(best)


def batch_rate(n_elements: int, samples: int, repeats: int = 3) -> float:
    """Samples per second of :func:`simulate` (compiled beforehand)."""
    params = full_model(n_elements)
    x, v = trajectory(samples)
    simulate(params, x[:10], v[:10])
    return samples / _best_seconds(lambda: simulate(params, x, v), repeats)


def step_percentiles_us(n_elements: int, calls: int) -> dict[str, float]:
    """Latency of :meth:`GmsStream.step` from Python, perf_counter_ns around each call."""
    stream = GmsStream(full_model(n_elements))
    x, v = trajectory(calls)
    xs, vs = x.tolist(), v.tolist()
    stream.step(xs[0], vs[0])
    times = np.empty(calls)
    clock = time.perf_counter_ns
    for i in range(calls):
        start = clock()
        stream.step(xs[i], vs[i])
        times[i] = clock() - start
    p50, p99, p999 = np.percentile(times, [50, 99, 99.9]) / 1e3
    return {"p50": float(p50), "p99": float(p99), "p99.9": float(p999)}


def solve_ivp_rate(n_elements: int, samples: int) -> float:
    """Samples per second of the same equations written as an ODE for solve_ivp (RK45)."""
    p = full_model(n_elements)
    k, w = p.stiffness_N_per_m, p.limit_N
    rate, c_v, v_t = p.attraction_rate_per_s, p.slip_level, p.transition_velocity_m_s
    dt = 1.0 / SAMPLE_RATE_Hz
    _x, v = trajectory(samples)
    t = np.arange(samples) * dt

    def rhs(time_s: float, force: FloatArray) -> FloatArray:
        vel = float(np.interp(time_s, t, v))
        level = c_v + (1 - c_v) * np.exp(-((vel / v_t) ** 2))
        stuck = (np.abs(force) < w) | (force * vel < 0)
        slip = np.sign(vel) * (rate / level) * (np.sign(vel) * level * w - force)
        return np.where(stuck, k * vel, slip)

    def run() -> None:
        sol = solve_ivp(rhs, (0.0, t[-1]), np.zeros(n_elements), t_eval=t, max_step=dt)
        _ = sol.y.sum(axis=0) + p.viscous_Ns_per_m * v

    return samples / _best_seconds(run, 1)


def measure(quick: bool = False) -> dict[str, Any]:
    """All figures; ``quick`` shortens the runs (for a smoke test)."""
    scale = 10 if quick else 1
    batch = batch_rate(16, 2_000_000 // scale)
    ivp = solve_ivp_rate(16, 2_000 // scale)
    latency = step_percentiles_us(16, 200_000 // scale)
    return {
        "gms": {
            "batch_samples_per_s": batch,
            "step_p99_us": latency["p99"],
            "step_latency_us": latency,
            "solve_ivp_samples_per_s": ivp,
            "solve_ivp_ratio": batch / ivp,
            "batch_samples_per_s_by_elements": {
                str(n): batch_rate(n, 1_000_000 // scale) for n in (1, 4, 16, 64, 256)
            },
            "batch_samples_per_s_by_length": {
                str(m // scale): batch_rate(16, m // scale) for m in (10_000, 100_000, 3_000_000)
            },
            "elements": 16,
            "model": "slip level 1.2, attraction 2e4 1/s, viscous 0.5 N s/m",
        }
    }


def register(subparsers: Any) -> None:
    """Add the ``bench`` subcommand to ``subparsers``."""
    parser = subparsers.add_parser(
        "bench",
        help="measure the speed of the GMS model",
        description="Batch throughput, streaming step latency and the solve_ivp ratio.",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout only")
    parser.add_argument("--quick", action="store_true", help="shorter runs (less precise)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Measure and print the figures (JSON on stdout only with ``--json``)."""
    length = "a few seconds" if args.quick else "a minute or more; --quick for a short run"
    print(f"measuring the GMS kernel ({length})", file=sys.stderr, flush=True)
    result = measure(quick=args.quick)
    if args.json:
        print(json.dumps(result))
    else:
        g = result["gms"]
        print(
            f"batch {g['batch_samples_per_s'] / 1e6:.1f} M samples/s (N=16), "
            f"step p99 {g['step_p99_us']:.2f} us, solve_ivp ratio {g['solve_ivp_ratio']:.0f}x"
        )
    return 0
