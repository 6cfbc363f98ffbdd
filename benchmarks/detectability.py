"""Print the independent detectability figure of each hidden effect (tests/indepdetect.py).

One line per effect: trace (case-seed), effect, rms/noise, peak/noise, mf (matched-filter
SNR), left (matched-filter SNR of what a free-limit GMS baseline cannot absorb) and the
share the baseline absorbs; ``--json`` prints the rows as JSON. Each trace's wall time goes
to stderr.

    python benchmarks/detectability.py dwell_time-159 stribeck-147 --json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from indepdetect import detectability
from indepgen import CASES


def _trace(value: str) -> tuple[str, int]:
    case, _, seed = value.rpartition("-")
    if case not in CASES or not seed.isdigit():
        raise argparse.ArgumentTypeError(f"CASE-SEED expected (case one of {', '.join(CASES)})")
    return case, int(seed)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("traces", nargs="+", type=_trace, metavar="CASE-SEED")
    parser.add_argument("--json", action="store_true", help="print the rows as JSON")
    args = parser.parse_args(argv)
    rows: list[dict[str, str | float]] = []
    if not args.json:
        print(f"{'trace':<28} {'effect':<20} {'rms':>8} {'peak':>8} {'mf':>9} {'left':>9} absorbed")
    for case, seed in args.traces:
        start = time.perf_counter()
        result = detectability(case, seed)
        print(f"# {case}-{seed}: {time.perf_counter() - start:.1f} s", file=sys.stderr)
        for effect, f in result.items():
            rows.append({"trace": f"{case}-{seed}", "effect": effect, **f})
            if not args.json:
                print(
                    f"{case}-{seed:<{27 - len(case)}} {effect:<20} {f['rms']:8.2f} "
                    f"{f['peak']:8.2f} {f['mf']:9.1f} {f['left']:9.1f} {f['absorbed']:8.4f}"
                )
    if args.json:
        print(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
