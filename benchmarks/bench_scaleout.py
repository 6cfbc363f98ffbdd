"""Scale-out on a local Dask cluster, and a paper estimate for a catalogue and a fleet.

1. The same 16-point sweep (4 preloads x 4 friction coefficients, N = 16
   elements) serially and on a 2-worker local cluster; both must give the same
   tables.
2. Fleet diagnosis of ``--traces`` generated traces (16 of 100 000 samples each by
   default, like a day's identification run), serially and on the cluster.

The cluster's start-up (its processes, imports and numba kernels compiled in each
worker, the diagnosis's too) is timed apart from the runs, as on a cluster that serves
many jobs; the fleet's speed-up is given without it and with it. Prints JSON, including
how many workers an overnight (10 h) run of a 10 000-variant catalogue and of a
1 000-machine fleet needs.

    python benchmarks/bench_scaleout.py [--points-per-axis 4] [--elements 16] [--traces 16]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from gms_comp.app.commands.demo_trace import generate
from gms_comp.app.fleet import FleetJob, diagnose_fleet, diagnose_one
from gms_comp.app.scaleout import dask_client
from gms_comp.app.sweep import load_sweep, run_sweep
from gms_comp.config import default_config_path
from gms_comp.measured.traces import write_trace

NIGHT_S = 10 * 3600.0


def _sweep_file(folder: Path, per_axis: int, elements: int) -> Path:
    loads = [20.0 + 20.0 * i for i in range(per_axis)]
    mus = [0.8e-3 + 0.2e-3 * i for i in range(per_axis)]
    path = folder / "sweep.toml"
    path.write_text(
        f'[sweep]\nbase_config = "{default_config_path()}"\nelements = {elements}\n'
        f'[sweep.axes]\n"stand.ball_loads_N" = {loads}\n'
        f'"bearing.friction_coefficient" = {mus}\n'
    )
    return path


def _fleet_traces(folder: Path, n: int, samples: int) -> list[FleetJob]:
    """``n`` generated traces of about ``samples`` samples (the sample rate is raised)."""
    names = ["offset", "viscous", "position_ripple", "none"]
    base = generate("none", seed=0).trace.time_s.size  # at 1 kHz
    rate_Hz = 1000.0 * samples / base
    jobs = []
    for i in range(n):
        path = folder / f"trace_{i:03d}.csv"
        write_trace(path, generate(names[i % len(names)], seed=i, sample_rate_Hz=rate_Hz).trace)
        jobs.append(FleetJob(str(path)))
    return jobs


def _warm(_: int) -> int:
    from gms_comp.physics.config import load_ball_config
    from gms_comp.tables.reduction import reduce_to_gms

    reduce_to_gms(load_ball_config(), 4)
    return 0


def _estimate(jobs: int, seconds_per_job: float, tasks_per_s: float) -> dict[str, float]:
    """CPU time, workers for a 10 h night, and the worker count at which the scheduler
    (handing out ``tasks_per_s``) rather than the workers limits the throughput."""
    cpu_s = jobs * seconds_per_job
    return {
        "cpu_hours": round(cpu_s / 3600, 2),
        "workers_for_overnight_10h": int(np.ceil(cpu_s / NIGHT_S)),
        "workers_at_scheduler_limit": int(tasks_per_s * seconds_per_job),
    }


def _noop(i: int) -> int:
    return i


def _scheduler_tasks_per_s(client: Any, n: int = 2000) -> float:
    """Trivial tasks through the scheduler per second: the rate it can hand out work."""
    t0 = time.perf_counter()
    client.gather(client.map(_noop, range(n), pure=False))
    return n / (time.perf_counter() - t0)


def _fleet(jobs: list[FleetJob], client: Any, start_s: float) -> dict[str, Any]:
    """Fleet diagnosis timed serially and on ``client`` (started in ``start_s``; the
    diagnosis's warm-up on each worker is timed apart too)."""
    diagnose_one(jobs[0])
    t0 = time.perf_counter()
    client.run(diagnose_one, jobs[0])
    warm_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    serial = diagnose_fleet(jobs, progress=False)
    serial_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    parallel = diagnose_fleet(jobs, client=client, progress=False)
    dask_s = time.perf_counter() - t0
    return {
        "traces": len(jobs),
        "serial_s": round(serial_s, 3),
        "dask_2_workers_s": round(dask_s, 3),
        "speedup": round(serial_s / dask_s, 3),
        "cluster_start_s": round(start_s, 3),
        "diagnosis_warm_up_s": round(warm_s, 3),
        "speedup_with_start_up": round(serial_s / (dask_s + start_s + warm_s), 3),
        "identical_rows": serial == parallel,
        "time_per_trace_s": round(serial_s / len(jobs), 3),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points-per-axis", type=int, default=4)
    parser.add_argument("--elements", type=int, default=16)
    parser.add_argument("--traces", type=int, default=16, help="fleet size (0: skip the fleet)")
    parser.add_argument("--samples", type=int, default=100_000, help="samples per fleet trace")
    args = parser.parse_args()
    report: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        spec = load_sweep(_sweep_file(root, args.points_per_axis, args.elements))
        _warm(0)
        t0 = time.perf_counter()
        serial = run_sweep(spec, root / "serial", progress=False)
        serial_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        with dask_client(n_workers=2) as client:
            client.run(_warm, 0)  # on every worker: numba caches loaded, imports done
            start_s = time.perf_counter() - t0
            t0 = time.perf_counter()
            parallel = run_sweep(spec, root / "dask", client=client, progress=False)
            dask_s = time.perf_counter() - t0
            if args.traces:
                jobs = _fleet_traces(root, args.traces, args.samples)
                report["fleet"] = _fleet(jobs, client, start_s)
                report["fleet"]["samples_per_trace"] = args.samples
            tasks_per_s = _scheduler_tasks_per_s(client)
    n = len(serial["points"])
    per_point = serial_s / n
    report["sweep"] = {
        "points": n,
        "elements": args.elements,
        "serial_s": round(serial_s, 3),
        "dask_2_workers_s": round(dask_s, 3),
        "speedup": round(serial_s / dask_s, 3),
        "identical_fidelity": all(
            a["fidelity"] == b["fidelity"]
            for a, b in zip(serial["points"], parallel["points"], strict=True)
        ),
        "time_per_point_s": round(per_point, 3),
    }
    report["scheduler_tasks_per_s"] = round(tasks_per_s, 1)
    report["estimate_10000_variants"] = _estimate(10_000, per_point, tasks_per_s)
    if "fleet" in report:
        report["estimate_1000_machines"] = _estimate(
            1_000, report["fleet"]["time_per_trace_s"], tasks_per_s
        )
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
