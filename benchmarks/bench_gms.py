"""Speed of the GMS model; prints JSON. Same code as ``gms-comp bench --json``.

Run: ``python benchmarks/bench_gms.py [--quick]``.
"""

from __future__ import annotations

import json
import sys

from gms_comp.app.commands.bench import measure

if __name__ == "__main__":
    print(json.dumps(measure(quick="--quick" in sys.argv[1:]), indent=1))
