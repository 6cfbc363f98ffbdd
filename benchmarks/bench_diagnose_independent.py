"""Benchmark the diagnosis blind, on traces from the independent generator (tests/indepgen.py).

Every case over N seeds (101, 102, ..., or from ``--first-seed``): generate, write the
canonical CSV, run ``python -m gms_comp diagnose CSV --json`` and time the call (wall
clock). Prints a markdown table (hit rate per case, false positives on ``none``, unknown
rate, pair-order rate, effects named that a trace does not hold, parameter errors,
median, 90th percentile and worst time), or with ``--json`` the
per-trace rows as JSON;
``-o FILE`` writes the JSON rows (after every trace); ``--rows FILE...`` prints the table of
saved rows without running anything (their main parameters judged again, by today's rule).

    python benchmarks/bench_diagnose_independent.py --seeds 1 --jobs 2 -o indep.json

``--noise-cutoff 0.05`` low-passes the force noise at 5 % of each trace's sample rate (a
sensor's or a drive's filter), at the same standard deviation.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from statistics import median, quantiles
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from indepdiag import TOLERANCE, main_parameter_error, pair_in_order, timed_diagnose
from indepgen import (
    CASES,
    CATALOGUE,
    UNKNOWN,
    baseline,
    dwell_gain,
    make_trace,
    median_standstill,
    parameter_error,
    write_csv,
)

from gms_comp.arguments import output_file
from gms_comp.atomic import write_text

FIRST_SEED = 101


def _jobs(value: str) -> int:
    jobs = int(value)
    if jobs not in (1, 2):
        raise argparse.ArgumentTypeError("1 or 2 (the machine has 2 cores)")
    return jobs


def _fraction(value: str) -> float:
    fraction = float(value)
    if not 0.0 < fraction < 0.5:
        raise argparse.ArgumentTypeError("a fraction of the sample rate below the Nyquist 0.5")
    return fraction


def _cases(value: str) -> list[str]:
    chosen = [c.strip() for c in value.split(",") if c.strip()]
    wrong = [c for c in chosen if c not in CASES]
    if wrong:
        raise argparse.ArgumentTypeError(f"unknown case(s) {wrong}; choose from {', '.join(CASES)}")
    return chosen


def run_one(
    case: str, seed: int, samples: int | None, timeout_s: float, folder: Path,
    noise_cutoff: float | None = None,
) -> dict[str, Any]:  # fmt: skip
    """Generate, diagnose and judge one trace; one row of the benchmark (``noise_cutoff``:
    the force noise low-passed at this fraction of the trace's sample rate)."""
    gen = make_trace(case, seed, samples)
    cutoff_Hz = None if noise_cutoff is None else noise_cutoff * gen.sample_rate_Hz
    if cutoff_Hz is not None:
        gen = make_trace(case, seed, samples, noise_cutoff_Hz=cutoff_Hz)
    path = write_csv(gen, folder / f"{case}_{seed}.csv")
    row: dict[str, Any] = {
        "case": case,
        "seed": seed,
        "expected": gen.expected,
        "truth": [[name, params] for name, params in gen.effects],
        "samples": int(gen.time_s.size),
        "C_v": gen.C_v,
        "n_elements": gen.n_elements,
        "sliding_force_N": gen.sliding_force_N,
        "noise_N": gen.noise_N,
        "sample_rate_Hz": gen.sample_rate_Hz,
        "quantisation_m": gen.quantisation_m,
        "noise_cutoff_Hz": cutoff_Hz,
    }
    try:
        outcome = timed_diagnose(path, timeout_s)
    except subprocess.TimeoutExpired:
        return row | {"status": "timeout", "named": None, "ranked": [], "seconds": timeout_s}
    except (RuntimeError, ValueError) as err:  # non-zero exit or unreadable JSON
        return row | {"status": f"error: {err}", "named": None, "ranked": [], "seconds": None}
    finally:
        path.unlink(missing_ok=True)
    error = main_parameter_error(gen, outcome)
    row |= {
        "status": "ok",
        "named": outcome.named,
        "ranked": outcome.ranked,
        "parameters": outcome.result.get("parameters"),
        "gain": outcome.result.get("gain"),
        "main_parameter_error": error,
        "within_tolerance": None if error is None else error <= TOLERANCE[gen.expected],
        "pair_in_order": pair_in_order(gen, outcome) if case.startswith("pair_") else None,
        "structure": outcome.result.get("structure"),  # why unknown (or not): the findings
        # what the baseline and the extended model hold out, against the noise
        "baseline_rms_N": outcome.result.get("baseline_rms_N"),
        "extended_rms_N": outcome.result.get("extended_rms_N"),
        "noise_rms_N": outcome.result.get("noise_rms_N"),
        "seconds": outcome.seconds,
        # what the trace could not tell apart, as the diagnosis says it
        "caveats": [c["kind"] for c in outcome.result.get("caveats", [])],
        # each kept effect's 95 % intervals, and what none rules out on this trace
        "intervals": {
            e["effect"]: e.get("intervals_95", {}) for e in outcome.result.get("effects") or []
        },
        "detection_limits": outcome.result.get("detection_limits"),
    }
    return row


def _caveats(rows: list[dict[str, Any]]) -> str:
    """How many traces carry each kind of caveat, among those named right and wrong
    (a caveat belongs on the wrong ones)."""
    kinds = sorted({k for r in rows for k in r.get("caveats") or ()})
    if not kinds:
        return "none given"
    right = [r for r in rows if _right(r)]
    wrong = [r for r in rows if not _right(r)]
    return "; ".join(
        f"{k} on {_count(right, lambda r, k=k: k in (r.get('caveats') or ()))} named right, "
        f"{_count(wrong, lambda r, k=k: k in (r.get('caveats') or ()))} named wrong"
        for k in kinds
    )


def _count(rows: list[dict[str, Any]], hit: Any) -> str:
    return f"{sum(bool(hit(r)) for r in rows)}/{len(rows)}" if rows else "-"


def _right(row: dict[str, Any]) -> bool:
    """Named right: the expected effect, or a pair in order (a row that failed, a
    timeout or a refused trace, has no pair order)."""
    if row["case"].startswith("pair_"):
        return bool(row.get("pair_in_order"))
    return bool(row["named"] == row["expected"])


def _case_line(mine: list[dict[str, Any]]) -> str:
    case = mine[0]["case"]
    hits = _count(mine, _right)
    named = ", ".join(
        (r["named"] or r["status"]) + (f" ({' > '.join(r['ranked'])})" if r["ranked"] else "")
        for r in mine
    )
    errors = [r["main_parameter_error"] for r in mine if r.get("main_parameter_error") is not None]
    error = f"{median(errors):.0%} / {max(errors):.0%}" if errors else "-"
    judged = [r for r in mine if r.get("within_tolerance") is not None]
    seconds = [r["seconds"] for r in mine if r["seconds"] is not None]
    took = f"{median(seconds):.0f} / {max(seconds):.0f}" if seconds else "-"
    within = _count(judged, lambda r: r["within_tolerance"])
    return f"| {case} | {mine[0]['expected']} | {hits} | {named} | {error} | {within} | {took} |"


def _truth_of(row: dict[str, Any]) -> dict[str, float]:
    """The expected effect's true parameters in ``row`` (a dwell's median standstill
    computed again for rows saved before it was part of the truth)."""
    truth = dict({name: dict(params) for name, params in row["truth"]}[row["expected"]])
    if row["expected"] == "dwell_time" and "median_standstill_s" not in truth:
        motion = baseline(row["seed"])[0]
        if motion.time_s.size != row["samples"]:  # a run with --samples
            motion = baseline(row["seed"], row["samples"])[0]
        truth["median_standstill_s"] = median_standstill(motion)
    return truth


def rejudged(row: dict[str, Any]) -> dict[str, Any]:
    """A saved row's main-parameter error judged again by today's ``parameter_error``
    (where the effect named first is the expected one, whose parameters the row holds)."""
    if row.get("named") != row["expected"] or row["expected"] not in TOLERANCE:
        return row
    error = parameter_error(row["expected"], _truth_of(row), row["parameters"])
    return row | {
        "main_parameter_error": error,
        "within_tolerance": error <= TOLERANCE[row["expected"]],
    }


def _gamma_alone(rows: list[dict[str, Any]]) -> str:
    """How many named dwell gains have gamma itself within the tolerance."""
    named = [r for r in rows if r["case"] == "dwell_time" and r.get("named") == "dwell_time"]
    return _count(
        named,
        lambda r: (
            abs(r["parameters"]["gamma"] / dict(r["truth"])["dwell_time"]["gamma"] - 1.0)
            <= TOLERANCE["dwell_time"]
        ),
    )


def _not_held(rows: list[dict[str, Any]]) -> str:
    """How many traces with known effects (catalogue and pair cases) have an effect named
    (first or later) that the trace does not hold, and which effects those were."""
    extra: Counter[str] = Counter()
    traces = 0
    for r in rows:
        held = {name for name, _ in r["truth"]}
        wrong = [name for name in r["ranked"] if name not in held]
        extra.update(wrong)
        traces += bool(wrong)
    which = ", ".join(f"{name} {n}" for name, n in extra.most_common())
    return f"{traces}/{len(rows)}" + (f" ({which})" if which else "")


def _coverage(rows: list[dict[str, Any]]) -> str:
    """Intervals holding the truth over all the rows, and by effect."""
    by: Counter[str] = Counter()
    held: Counter[str] = Counter()
    for r in rows:
        for effect in r.get("intervals") or {}:
            single = {**r, "intervals": {effect: r["intervals"][effect]}}
            inside, total = covered(single)
            held[effect] += inside
            by[effect] += total
    inside, total = sum(held.values()), sum(by.values())
    if not total:
        return "none given"
    each = ", ".join(f"{k} {held[k]}/{by[k]}" for k in sorted(by))
    return f"{inside}/{total} ({inside / total:.0%}; {each})"


def _times(seconds: list[float]) -> str:
    """Median, 90th percentile and worst time, and how many took over 15 s and 60 s."""
    if not seconds:
        return "-"
    p90 = quantiles(seconds, n=10)[8] if len(seconds) > 1 else seconds[0]
    over = {limit: sum(s > limit for s in seconds) for limit in (15.0, 60.0)}
    return (
        f"median {median(seconds):.1f} s, 90th percentile {p90:.1f} s, worst "
        f"{max(seconds):.1f} s; over 15 s: {over[15.0]}/{len(seconds)}, over 60 s: "
        f"{over[60.0]}/{len(seconds)}"
    )


def covered(row: dict[str, Any]) -> tuple[int, int]:
    """How many of the intervals given for effects the trace holds contain the truth, of
    how many (the truth's parameters by the same names; a dwell gain's after the trace's
    median standstill too)."""
    truth = {name: dict(params) for name, params in row["truth"]}
    inside = total = 0
    for effect, bounds in (row.get("intervals") or {}).items():
        if effect not in truth:
            continue
        want = dict(truth[effect])
        if effect == "dwell_time" and "median_standstill_s" in want:
            want["gain_after_median_dwell"] = dwell_gain(want, want["median_standstill_s"])
        for name, (lo, hi) in bounds.items():
            if name in want and name != "median_dwell_s":
                value = want[name]
                if name == "phase_rad":  # on the turn of the interval's middle
                    middle = 0.5 * (lo + hi)
                    value = middle + math.remainder(value - middle, 2 * math.pi)
                total += 1
                inside += int(lo <= value <= hi)
    return inside, total


def table(rows: list[dict[str, Any]]) -> str:
    """The markdown summary of the rows: one line per case, then the totals."""
    lines = [
        "| case | expected | hit | named (ranked) | param err med/worst | in tol. | s med/worst |",
        "|---|---|---|---|---|---|---|",
    ]
    for case in dict.fromkeys(r["case"] for r in rows):
        lines.append(_case_line([r for r in rows if r["case"] == case]))
    catalogue = [r for r in rows if r["case"] in CATALOGUE]
    none = [r for r in rows if r["case"] == "none"]
    unknown = [r for r in rows if r["case"] in UNKNOWN]
    pairs = [r for r in rows if r["case"].startswith("pair_")]
    seconds = [r["seconds"] for r in rows if r["seconds"] is not None]
    named_first = _count(catalogue, lambda r: r["named"] == r["case"])
    lines += [
        "",
        f"- catalogue effects named first: {named_first}; main parameter within tolerance: "
        + _count(catalogue, lambda r: r.get("within_tolerance")),
        "- dwell_time judged by its gain after the median standstill; gamma alone within "
        f"tolerance: {_gamma_alone(rows)} (gamma trades with tau along the dwells)",
        f"- false positives on effect-free traces: {_count(none, lambda r: r['named'] != 'none')}",
        "- traces with known effects where an effect the trace does not hold is named "
        f"(first or later): {_not_held(catalogue + pairs)}",
        "- uncatalogued effects called unknown: "
        + _count(unknown, lambda r: r["named"] == "unknown"),
        f"- pairs in the right order: {_count(pairs, lambda r: r.get('pair_in_order'))}",
        f"- caveats: {_caveats(catalogue + pairs)}",
        f"- 95 % intervals holding the truth: {_coverage(catalogue + pairs)}",
        f"- timeouts: {_count(rows, lambda r: r['status'] == 'timeout')}, errors: "
        + _count(rows, lambda r: r["status"].startswith("error")),
        f"- time per diagnosis: {_times(seconds)}",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; return the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="seeds per case (default 5)")
    parser.add_argument(
        "--first-seed", type=int, default=FIRST_SEED,
        help=f"first seed (default {FIRST_SEED}; a later one: seeds no change was tuned on)",
    )  # fmt: skip
    parser.add_argument(
        "--cases", type=_cases, default=list(CASES), help="comma-separated cases (default all)"
    )
    parser.add_argument(
        "--samples", type=int, default=None, help="trace length (default 100k-200k by seed)"
    )
    parser.add_argument("--jobs", type=_jobs, default=1, help="diagnoses at once, 1 or 2")
    parser.add_argument(
        "--noise-cutoff", type=_fraction, default=None, metavar="FRACTION",
        help="low-pass the force noise at this fraction of the sample rate (default: white)",
    )  # fmt: skip
    parser.add_argument(
        "--timeout", type=float, default=900.0, help="seconds per diagnosis (default 900)"
    )
    parser.add_argument(
        "--json", action="store_true", help="print the rows as JSON instead of the table"
    )
    parser.add_argument("-o", "--output", type=output_file, help="write the rows as JSON here")
    parser.add_argument(
        "--rows", nargs="+", type=Path, help="no run: print the table of rows saved with -o"
    )
    args = parser.parse_args(argv)
    if args.rows:
        saved = [rejudged(row) for path in args.rows for row in json.loads(path.read_text())]
        print(table(saved))
        return 0
    work = [(case, args.first_seed + i) for i in range(args.seeds) for case in args.cases]
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as folder, ThreadPoolExecutor(args.jobs) as pool:
        futures = [
            pool.submit(run_one, c, s, args.samples, args.timeout, Path(folder), args.noise_cutoff)
            for c, s in work
        ]
        for future in futures:
            row = future.result()
            rows.append(row)
            took = "-" if row["seconds"] is None else f"{row['seconds']:.1f} s"
            print(
                f"{row['case']} seed {row['seed']}: {row['named'] or row['status']} "
                f"(expected {row['expected']}) {took}",
                file=sys.stderr,
                flush=True,
            )
            if args.output:  # rewritten after every trace: a long run keeps what it has
                write_text(args.output, json.dumps(rows, indent=1, default=float))
    if args.output:
        print(f"wrote {args.output}", file=sys.stderr)
    print(json.dumps(rows, indent=1, default=float) if args.json else table(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
