"""Sweep speed-up on a local Dask cluster, and a paper estimate for a whole catalogue.

Runs the same 16-point sweep (4 preloads x 4 friction coefficients, N = 16
elements) serially and on a 2-worker local cluster, checks that both give the
same tables, and prints JSON. The cluster is started and warmed up (numba
kernels compiled in each worker) before the timed run, as it would be on a
cluster that serves many sweeps.

    python benchmarks/bench_sweep.py [--points-per-axis 4] [--elements 16]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

from gms_comp.config import default_config_path
from gms_comp.scaleout import dask_client, run_jobs
from gms_comp.sweep import load_sweep, run_sweep

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


def _warm(_: int) -> int:
    from gms_comp.config import load_ball_config
    from gms_comp.reduction import reduce_to_gms

    reduce_to_gms(load_ball_config(), 4)
    return 0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points-per-axis", type=int, default=4)
    parser.add_argument("--elements", type=int, default=16)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        spec = load_sweep(_sweep_file(root, args.points_per_axis, args.elements))
        _warm(0)
        t0 = time.perf_counter()
        serial = run_sweep(spec, root / "serial", progress=False)
        serial_s = time.perf_counter() - t0
        with dask_client(n_workers=2) as client:
            list(run_jobs(_warm, [0, 1], client=client))
            t0 = time.perf_counter()
            parallel = run_sweep(spec, root / "dask", client=client, progress=False)
            dask_s = time.perf_counter() - t0
    n = len(serial["points"])
    same = all(
        a["fidelity"] == b["fidelity"]
        for a, b in zip(serial["points"], parallel["points"], strict=True)
    )
    per_point = serial_s / n
    report: dict[str, Any] = {
        "points": n,
        "elements": args.elements,
        "serial_s": round(serial_s, 3),
        "dask_2_workers_s": round(dask_s, 3),
        "speedup": round(serial_s / dask_s, 3),
        "identical_fidelity": same,
        "time_per_point_s": round(per_point, 3),
        "estimate_10000_variants": {
            "cpu_hours": round(10_000 * per_point / 3600, 2),
            "workers_for_overnight_10h": max(1, int(10_000 * per_point / NIGHT_S) + 1),
        },
    }
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
