"""Check the diagnosis's detection limits on the independent generator (tests/indepgen.py).

For each seed: diagnose its effect-free trace, read the smallest size of each catalogue
effect that trace would have revealed (the JSON's ``detection_limits``), then diagnose the
same trace (same motion, baseline and noise) with that effect added at twice and at half
its limit. A limit that holds: found (named, first or later) at twice in at least 90 % of
the traces, at half in at most 20 %. "Size" is the effect's main parameter as the generator
sizes it (``ratio - 1`` for stribeck, ``1 / cutoff`` for sensor_lowpass, the parameter
itself for the others), so the check does not take the diagnosis's word for it.

    python benchmarks/bench_detection.py --seeds 10 --first-seed 300 --jobs 2 -o det.json
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from indepdiag import scaled, timed_diagnose
from indepgen import CATALOGUE, make_trace, with_effect, write_csv

from gms_comp.arguments import output_file
from gms_comp.atomic import write_text

FACTORS = (2.0, 0.5)


def _diagnosed(gen: Any, folder: Path, tag: str, timeout_s: float) -> dict[str, Any]:
    path = write_csv(gen, folder / f"{tag}.csv")
    try:
        outcome = timed_diagnose(path, timeout_s)
    except (RuntimeError, ValueError) as err:
        return {"status": f"error: {err}", "ranked": [], "seconds": None}
    finally:
        path.unlink(missing_ok=True)
    return {
        "status": "ok",
        "named": outcome.named,
        "ranked": outcome.ranked,
        "seconds": outcome.seconds,
        "result": outcome.result,
    }


def run_seed(
    seed: int, folder: Path, timeout_s: float, pool: ThreadPoolExecutor
) -> list[dict[str, Any]]:
    """The effect-free trace of ``seed`` and its injected traces, one row each."""
    free = _diagnosed(make_trace("none", seed), folder, f"none_{seed}", timeout_s)
    limits = (free.get("result") or {}).get("detection_limits") or {}
    rows = [{"seed": seed, "effect": None, "factor": None, "named": free.get("named"),
             "seconds": free["seconds"], "limits": limits}]  # fmt: skip
    jobs = []
    for name in CATALOGUE:
        if name not in limits:
            continue
        for factor in FACTORS:
            params = scaled(name, limits[name], factor)
            gen = with_effect(seed, name, params)
            tag = f"{name}_{seed}_{factor}"
            jobs.append(
                (name, factor, params, pool.submit(_diagnosed, gen, folder, tag, timeout_s))
            )
    for name, factor, params, future in jobs:
        out = future.result()
        rows.append({
            "seed": seed, "effect": name, "factor": factor, "params": params,
            "named": out.get("named"), "ranked": out["ranked"], "seconds": out["seconds"],
            "found": name in out["ranked"], "status": out["status"],
        })  # fmt: skip
        print(f"{name} seed {seed} x{factor}: {out.get('named')} {out['ranked']}",
              file=sys.stderr, flush=True)  # fmt: skip
    return rows


def table(rows: list[dict[str, Any]]) -> str:
    """Found at twice and at half the limit, per effect and in all."""
    found: Counter[tuple[str, float]] = Counter()
    count: Counter[tuple[str, float]] = Counter()
    for r in rows:
        if r["effect"] is None:
            continue
        count[r["effect"], r["factor"]] += 1
        found[r["effect"], r["factor"]] += int(bool(r.get("found")))
    lines = ["| effect | found at 2 x the limit | found at 0.5 x |", "|---|---|---|"]
    for name in CATALOGUE:
        cells = [f"{found[name, f]}/{count[name, f]}" for f in FACTORS]
        if any(count[name, f] for f in FACTORS):
            lines.append(f"| {name} | {cells[0]} | {cells[1]} |")
    totals = []
    for f in FACTORS:
        k = sum(found[n, f] for n in CATALOGUE)
        n = sum(count[e, f] for e in CATALOGUE)
        totals.append(f"{k}/{n} ({k / n:.0%})" if n else "-")
    free = [r for r in rows if r["effect"] is None]
    none = sum(r["named"] == "none" for r in free)
    seconds = sorted(r["seconds"] for r in rows if r.get("seconds") is not None)
    lines += [
        f"| all | {totals[0]} | {totals[1]} |",
        "",
        f"- effect-free traces named none: {none}/{len(free)}",
        f"- median time {seconds[len(seconds) // 2]:.1f} s, worst {seconds[-1]:.1f} s"
        if seconds
        else "- no times",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run the check; return the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="seeds (default 5)")
    parser.add_argument("--first-seed", type=int, default=300, help="first seed (default 300)")
    parser.add_argument("--jobs", type=int, choices=(1, 2), default=1, help="diagnoses at once")
    parser.add_argument("--timeout", type=float, default=900.0, help="seconds per diagnosis")
    parser.add_argument("-o", "--output", type=output_file, help="write the rows as JSON here")
    parser.add_argument("--rows", nargs="+", type=Path, help="no run: the table of saved rows")
    args = parser.parse_args(argv)
    if args.rows:
        print(table([row for path in args.rows for row in json.loads(path.read_text())]))
        return 0
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as folder, ThreadPoolExecutor(args.jobs) as pool:
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            rows += run_seed(seed, Path(folder), args.timeout, pool)
            if args.output:
                write_text(args.output, json.dumps(rows, indent=1, default=float))
    print(table(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
