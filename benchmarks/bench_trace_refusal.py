"""Time and memory to refuse a huge CSV trace, from its size and its first rows.

Writes 256 MB CSV files (``--folder``, default a temporary one) whose rows are short (19
bytes: refused from the estimate of its rows) or longer (96 bytes: 2.8 million rows, near
the estimate's margin, refused by counting them in chunks), and for each prints as JSON:

- ``load_trace_s`` / ``load_trace_peak_MB``: :func:`load_trace` alone, in a fresh process
  (peak resident memory of that process, less the same process's after the imports);
- ``cli_s``: ``gms-comp diagnose FILE`` end to end, with ``cli_start_s``, the same
  command on a missing file (the interpreter and imports, which any refusal pays);
- the refusal's line.

    python benchmarks/bench_trace_refusal.py [--folder DIR]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SIZE = 256 << 20
ROWS = {
    "short_rows": b"0.001,0.000001,1.5\n",
    "long_rows": b"0.00100000000000000000,0.00000100000000000000000,1.50000000000000000000000,"
    b"0.000000000000000000\n",
}
HEADER = {
    "short_rows": b"time_s,position_m,force_N\n",
    "long_rows": b"time_s,position_m,force_N,velocity_m_s\n",
}

PROBE = """
import json, resource, sys, time
from gms_comp.errors import TraceError
from gms_comp.measured.traces import load_trace
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
start = time.perf_counter()
try:
    load_trace(sys.argv[1])
    said = "accepted"
except TraceError as err:
    said = str(err)
seconds = time.perf_counter() - start
after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"s": seconds, "peak_MB": (after - before) / 1024, "said": said}))
"""


def _write(path: Path, header: bytes, row: bytes) -> None:
    block = row * (1 << 16)
    with path.open("wb") as fh:
        fh.write(header)
        while fh.tell() + len(block) < SIZE:
            fh.write(block)
        fh.write(row * ((SIZE - fh.tell()) // len(row)))


def _cli_seconds(path: Path) -> float:
    start = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "gms_comp", "diagnose", str(path)], capture_output=True, check=False
    )
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folder", type=Path, default=None)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.folder or Path(tmp)
        results = {}
        start_s = _cli_seconds(folder / "missing.csv")
        for name, row in ROWS.items():
            path = folder / f"{name}.csv"
            _write(path, HEADER[name], row)
            probe = subprocess.run(
                [sys.executable, "-c", PROBE, str(path)], capture_output=True, text=True, check=True
            )
            found = json.loads(probe.stdout)
            results[name] = {
                "bytes": path.stat().st_size,
                "load_trace_s": round(found["s"], 4),
                "load_trace_peak_MB": round(found["peak_MB"], 1),
                "cli_s": round(_cli_seconds(path), 2),
                "cli_start_s": round(start_s, 2),
                "said": found["said"],
            }
            path.unlink()
    print(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
