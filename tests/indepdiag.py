"""Black-box use of ``gms-comp diagnose`` on independent traces, shared by the blind tests
and the benchmark: run the CLI, read its JSON, judge the answer against the truth."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from indepgen import CATALOGUE, MAIN_PARAMETER, Generated, parameter_error

# Tolerance on the main parameter's relative error (of ratio - 1 for stribeck), per effect.
# Tight where the effect is a direct regressor on well-excited data, looser where the
# parameter trades against a second one or against the baseline's own shape:
TOLERANCE = {
    "offset": 0.10,  # a constant, >= 10 % of the level, averaged over every sample
    "position_ripple": 0.15,  # a sinusoid in x, many periods over the stroke
    "inertia": 0.15,  # m a, with a the second derivative of a quantised position
    "viscous": 0.20,  # c v trades a little against the baseline's C_v rise (below 1 mm/s)
    "sensor_lowpass": 0.25,  # cut-off seen only through the edges of fast force changes
    "drift": 0.25,  # kappa trades against tau when tau is a good part of the trace
    "stribeck": 0.30,  # ratio - 1 trades against v_s and the baseline's onset velocity
    "reversal_transient": 0.30,  # A trades against its length and the presliding curve
    "dwell_time": 0.35,  # the gain after the median standstill, seen at break-aways only
}
assert set(TOLERANCE) == set(CATALOGUE)


@dataclass(frozen=True)
class Outcome:
    """What the diagnosis said about one trace, and how long it took (wall clock)."""

    result: dict[str, Any]
    seconds: float

    @property
    def named(self) -> str:
        """The effect named first (catalogue name, ``none`` or ``unknown``)."""
        return str(self.result.get("effect"))

    @property
    def ranked(self) -> list[str]:
        """Names of the kept effects, in the diagnosis's ranking."""
        return [str(entry.get("effect")) for entry in self.result.get("effects") or []]

    def fitted(self, effect: str) -> dict[str, float] | None:
        """The fitted parameters of ``effect`` (the ranked entry, else the top-level one)."""
        for entry in self.result.get("effects") or []:
            if entry.get("effect") == effect:
                return dict(entry.get("parameters") or {})
        if self.named == effect:
            return dict(self.result.get("parameters") or {})
        return None


def run_diagnose(csv_path: Path, timeout_s: float = 900.0) -> dict[str, Any]:
    """Run ``python -m gms_comp diagnose CSV --json`` and return its JSON result."""
    return timed_diagnose(csv_path, timeout_s).result


def timed_diagnose(csv_path: Path, timeout_s: float = 900.0) -> Outcome:
    """``run_diagnose`` with the wall-clock time of the CLI call."""
    command = [sys.executable, "-m", "gms_comp", "diagnose", str(csv_path), "--json"]
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, timeout=timeout_s)
    seconds = time.perf_counter() - start
    _check(done, csv_path)
    return Outcome(json.loads(done.stdout), seconds)


def _check(done: subprocess.CompletedProcess[str], csv_path: Path) -> None:
    if done.returncode != 0:
        tail = done.stderr.strip().splitlines()[-3:]
        raise RuntimeError(f"diagnose {csv_path.name} exited {done.returncode}: {' | '.join(tail)}")


def main_parameter_error(gen: Generated, outcome: Outcome) -> float | None:
    """Relative error of the expected effect's main parameter, if the diagnosis fitted it."""
    if gen.expected not in MAIN_PARAMETER:
        return None
    fitted = outcome.fitted(gen.expected)
    truth = dict(gen.effects)[gen.expected]
    if fitted is None or MAIN_PARAMETER[gen.expected] not in fitted:
        return None
    return parameter_error(gen.expected, truth, fitted)


def pair_in_order(gen: Generated, outcome: Outcome) -> bool:
    """Both effects of a pair kept, the larger one named first and ranked above the other."""
    big, small = (name for name, _ in gen.effects)
    ranked = outcome.ranked
    return (
        outcome.named == big
        and big in ranked
        and small in ranked
        and ranked.index(big) < ranked.index(small)
    )


def scaled(name: str, params: dict[str, float], factor: float) -> dict[str, float]:
    """``params`` of the effect ``name`` with its size (its main parameter, as the
    generator sizes it) times ``factor``: ``ratio - 1`` for stribeck, ``1 / cutoff`` for
    sensor_lowpass (a lower cut-off is a larger filter), the parameter itself otherwise."""
    key = MAIN_PARAMETER[name]
    out = dict(params)
    if key == "ratio":
        out[key] = 1.0 + (params[key] - 1.0) * factor
    elif name == "sensor_lowpass":
        out[key] = params[key] / factor
    else:
        out[key] = params[key] * factor
    return out
