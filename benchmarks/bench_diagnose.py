"""Time ``diagnose`` on a 100 000-sample measured-like trace; print JSON."""

from __future__ import annotations

import json
import time

from gms_comp.diagnosis.run import diagnose
from sim.tracegen import generate


def main() -> None:
    g = generate("position_ripple", 0, scale=3.3)
    diagnose(generate("offset", 0).trace)  # numba compile outside the timing
    start = time.perf_counter()
    result = diagnose(g.trace)
    elapsed = time.perf_counter() - start
    print(json.dumps({"samples": len(g.trace), "seconds": round(elapsed, 2),
                      "effect": result.effect, "gain": round(result.gain, 3)}))  # fmt: skip


if __name__ == "__main__":
    main()
