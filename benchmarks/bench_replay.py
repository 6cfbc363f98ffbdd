"""Speed of the replay of a measured closed-loop run (issue 14); prints one JSON object.

Times :func:`gms_comp.app.replay.replay` alone (the record and model loaded beforehand, the
numba kernel compiled by a first call): one 24 841-sample EMPS record, 10 RK4 sub-steps
per cycle, best of ``--repeats``, for the benchmark's reference model and, with
``--model``, a GMS table. Target: at most 5 s.

Usage: ``python benchmarks/bench_replay.py [TRACE] [--model TABLE] [--repeats N]``
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

from gms_comp.app import replay

DEFAULT_TRACE = next(
    (
        p / "shared" / "data" / "emps" / "DATA_EMPS.mat"
        for p in Path(__file__).resolve().parents
        if (p / "shared" / "data" / "emps").is_dir()
    ),
    Path("../shared/data/emps/DATA_EMPS.mat"),
)


def main() -> None:
    """Time the replays and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("trace", nargs="?", default=str(DEFAULT_TRACE))
    parser.add_argument("--model", help="GMS table or diagnose JSON (besides the reference)")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    record = replay.load_record(args.trace)
    models = {"reference": replay.load_model(None)}
    if args.model:
        models["model"] = replay.load_model(args.model)
    out: dict[str, object] = {"trace": args.trace, "samples": int(record.reference_m.size)}
    for key, choice in models.items():
        replay.replay(record, choice.axis)  # compile / load the numba cache
        best = math.inf
        for _ in range(args.repeats):
            started = time.perf_counter()
            replay.replay(record, choice.axis)
            best = min(best, time.perf_counter() - started)
        out[f"{key}_replay_s"] = best
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
