"""The friction-level adaptation, measured on the simulated axis; prints one JSON object.

The default scenario's circle (servo 4 kHz, GMS feedforward from the physics table, one
cycle of transport), run long; the plant's friction level follows a schedule (the truth
pack's scale, changed between cycles), the adaptation reads the drive's current (with
measurement noise where asked) and the measured velocity, as a drive would give them.

- ``step_settle_s``: seconds from a +20 % step of the friction until the level stays
  within 5 % of the truth (1.2), adaptation on (target <= 10 s).
- ``drift_peak_ratio_on`` / ``_off``: over 10 min of a +30 % linear drift, the largest
  peak reversal error over the same run's without drift (target <= 1.3 on); with the
  level against the truth and the peak reversal error per minute.
- ``robustness``: off against on for a force constant 20 % high and low, 3 % current
  noise, a stuck axis (friction x 50 for 1 s), a collision-like spike (x 5 for 20 ms) and
  a long standstill with a friction step: the largest peak reversal error, the level's
  range, and whether it stayed within its bounds (target: on never worse than off by more
  than 10 %, never out of bounds, unchanged at standstill).

Usage: ``python benchmarks/bench_adaptation.py [--drift-s S] [--rate R]``
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.runtime.observer import FrictionObserver, adapt_level
from sim.closed_loop import run
from sim.controller import MEASURED_VELOCITY
from sim.link import DirectLink
from sim.scenarios import Loop, Physics, Scenario, load_scenario, reduced_table
from sim.trajectories import Reference, reversals

NOISE_OF_FRICTION = 0.03


class AdaptingDrive:
    """The direct link, plus what happens in the drive each cycle: the plant's friction
    level set from ``schedule``, and the adaptation fed the drive's current (plus noise)
    and the measured velocity, after the feedforward of the cycle was computed."""

    def __init__(
        self, loop: Loop, observer: FrictionObserver, gain_params: FloatArray,
        schedule: FloatArray, noise_A: float, kf_model: float, seed: int = 0,
    ) -> None:  # fmt: skip
        self.loop, self.observer, self.params = loop, observer, gain_params
        self.schedule, self.noise_A = schedule, noise_A
        self.inertial_A = loop.reference.acceleration_m_s2 * loop.scenario.plant.moving_mass_kg
        self.inertial_A /= kf_model
        self.link = DirectLink(loop.scenario.scenario.transport_delay_cycles)
        self.noise = np.random.default_rng(seed).standard_normal(schedule.size)
        self.level = np.zeros(schedule.size)
        self.base = 0.0

    def transfer(self, cycle: int, current_A: float) -> float:
        """Set the friction, adapt the level, pass the current on."""
        axis = self.loop.axis
        scale = axis.truth[1]
        if cycle == 0:
            self.base = float(scale[0])
        scale[0] = self.base * self.schedule[cycle]
        measured = axis.current_A + self.noise_A * self.noise[cycle]
        velocity = float(self.loop.controller.state[MEASURED_VELOCITY])
        adapt_level(self.observer.state, self.params, measured, self.inertial_A[cycle], velocity)
        self.level[cycle] = self.observer.level
        return self.link.transfer(cycle, current_A)


@dataclasses.dataclass(frozen=True)
class Run:
    """One run: the level per cycle and the peak error after each reversal."""

    time_s: FloatArray
    level: FloatArray
    reversal_time_s: FloatArray
    reversal_peak_m: FloatArray


def scenario(duration_s: float) -> Scenario:
    """The default circle, as many revolutions as ``duration_s`` takes."""
    s = load_scenario()
    c = s.scenario
    revolutions = duration_s * c.feed_m_s / (2 * math.pi * c.radius_m)
    return dataclasses.replace(s, scenario=dataclasses.replace(c, revolutions=revolutions))


def simulate(
    s: Scenario, schedule: Callable[[FloatArray], Any], rate_per_s: float,
    kf_error: float = 1.0, noise: bool = False, reference: Reference | None = None,
) -> Run:  # fmt: skip
    """The circle with the friction level ``schedule(t)``, adaptation at ``rate_per_s``."""
    loop = Loop.build(s, Physics())
    if reference is not None:
        loop = dataclasses.replace(loop, reference=reference)
    ref = loop.reference
    kf_model = s.plant.force_constant_N_per_A * kf_error
    comp = dataclasses.replace(s.compensator, adaptation_rate_per_s=rate_per_s)
    period = s.controller.servo_period_s
    observer = FrictionObserver(reduced_table(s), kf_model, period, 1.0, comp)
    params = observer.params.copy()
    observer.params[3] = 0.0  # the loop's own adaptation off: the drive adapts
    table = observer.model
    sliding_A = table.params.slip_level * float(table.params.limit_N.sum()) / kf_model  # type: ignore[attr-defined]
    t = ref.time_s
    drive = AdaptingDrive(
        loop, observer, params, schedule(t), NOISE_OF_FRICTION * sliding_A if noise else 0.0,
        kf_model,
    )  # fmt: skip
    r = run(ref, loop.axis, loop.controller, drive, observer, "reference", 1)
    error = np.abs(r.error_m)
    window = round(s.scenario.reversal_window_s / ref.period_s)
    turns = reversals(ref)
    peaks = np.array([error[k : k + window].max() for k in turns])
    return Run(t, drive.level, t[turns], peaks)


def settle_s(run_: Run, step_s: float, truth: float, within: float = 0.05) -> float | None:
    """Seconds after ``step_s`` until the level stays within ``within`` of ``truth``."""
    outside = np.flatnonzero(np.abs(run_.level / truth - 1.0) > within)
    last = run_.time_s[outside[-1]] if outside.size else run_.time_s[0]
    return None if last >= run_.time_s[-1] else max(0.0, float(last) - step_s)


def per_minute(run_: Run) -> list[float]:
    """The largest reversal peak (um) in each minute."""
    minute = (run_.reversal_time_s // 60).astype(int)
    return [float(run_.reversal_peak_m[minute == m].max() * 1e6) for m in np.unique(minute)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--drift-s", type=float, default=600.0)
    parser.add_argument("--rate", type=float, default=1.0, help="adaptation rate, 1/s")
    args = parser.parse_args()
    out: dict[str, Any] = {"adaptation_rate_per_s": args.rate}

    step_at = 5.0
    step = scenario(40.0)
    stepped = simulate(step, lambda t: 1.0 + 0.2 * (t >= step_at), args.rate)
    out["step_settle_s"] = settle_s(stepped, step_at, 1.2)
    out["step_level_at_s"] = {
        f"{dt:g}": float(np.interp(step_at + dt, stepped.time_s, stepped.level))
        for dt in (0.0, 1.0, 2.0, 5.0, 10.0, 30.0)
    }

    long = scenario(args.drift_s)

    def drift(t: FloatArray) -> FloatArray:
        return 1.0 + 0.3 * t / args.drift_s

    runs = {
        (name, rate): simulate(long, sched, rate)
        for name, sched in (("drift", drift), ("flat", lambda t: np.ones_like(t)))
        for rate in (0.0, args.rate)
    }
    for key, rate in (("on", args.rate), ("off", 0.0)):
        peak_drift = float(runs["drift", rate].reversal_peak_m.max())
        peak_flat = float(runs["flat", rate].reversal_peak_m.max())
        out[f"drift_peak_ratio_{key}"] = peak_drift / peak_flat
        out[f"drift_{key}"] = {
            "no_drift_peak_um": peak_flat * 1e6,
            "peak_um_per_minute": per_minute(runs["drift", rate]),
            "level_per_minute": [
                float(np.interp(m * 60.0, runs["drift", rate].time_s, runs["drift", rate].level))
                for m in range(1, int(args.drift_s // 60) + 1)
            ],
            "truth_per_minute": [
                float(drift(np.array([m * 60.0]))[0]) for m in range(1, int(args.drift_s // 60) + 1)
            ],
        }
    out["robustness"] = robustness(args.rate)
    json.dump(out, sys.stdout, indent=2)
    sys.stdout.write("\n")


def robustness(rate: float) -> dict[str, Any]:
    """Off against on under a wrong force constant, noise, a jam, a spike, a standstill."""
    s = scenario(30.0)
    lo, hi = s.compensator.adaptation_level_bounds
    cases: dict[str, dict[str, Any]] = {
        "force_constant_+20%": {"kf_error": 1.2},
        "force_constant_-20%": {"kf_error": 0.8},
        "noise_3%": {"noise": True},
        "stuck_axis": {"schedule": lambda t: 1.0 + 49.0 * ((t >= 10.0) & (t < 11.0))},
        "collision_spike": {"schedule": lambda t: 1.0 + 4.0 * ((t >= 10.0) & (t < 10.02))},
    }
    out: dict[str, Any] = {}
    for name, case in cases.items():
        sched = case.pop("schedule", lambda t: np.ones_like(t))
        on, off = (simulate(s, sched, r, **case) for r in (rate, 0.0))
        peak_on, peak_off = float(on.reversal_peak_m.max()), float(off.reversal_peak_m.max())
        out[name] = {
            "peak_on_um": peak_on * 1e6,
            "peak_off_um": peak_off * 1e6,
            "on_over_off": peak_on / peak_off,
            "level_min": float(on.level.min()),
            "level_max": float(on.level.max()),
            "within_bounds": bool(lo <= on.level.min() and on.level.max() <= hi),
        }
    still = load_scenario()
    n = round(30.0 / still.controller.servo_period_s)
    zero = np.zeros(n)
    rest = Reference(still.controller.servo_period_s, zero, zero, zero)
    stand = simulate(still, lambda t: 1.0 + 0.2 * (t >= 5.0), rate, reference=rest)
    out["standstill_30s"] = {"level_changed": bool(np.any(stand.level != stand.level[0]))}
    return out


if __name__ == "__main__":
    main()
