"""``gms-comp demo-trace``: a measured-like trace without hardware.

The truth GMS of :mod:`sim.tracegen` runs along the identification profile; one
catalogue effect (or none) is applied with :mod:`gms_comp.runtime.effects`, with parameters
drawn in ranges that matter for compensation (a tenth to a third of the sliding force),
then sensor noise and the encoder's and ADC's steps. It makes the README's
``gms-comp diagnose measured.csv`` runnable, and serves the project's own regression
tests of the diagnosis (its blind tests use the independent tests/indepgen.py).
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import json
import math
import sys
from dataclasses import dataclass
from typing import Any

import numpy as np

from gms_comp.arguments import int_in_range, output_file
from gms_comp.arrays import FloatArray
from gms_comp.atomic import write_text
from gms_comp.gms import GmsParams, scaled
from gms_comp.measured.traces import Trace
from gms_comp.runtime import effects as fx
from gms_comp.validation import MAX_SEED
from sim import tracegen

# The main parameter of each spec catalogue effect, as the diagnosis must recover it.
MAIN_PARAMETER = {
    "viscous": "c_Ns_per_m",
    "stribeck": "ratio",
    "dwell_time": "gamma",
    "position_ripple": "wavelength_m",
    "offset": "offset_N",
    "reversal_transient": "amplitude_N",
    "drift": "kappa",
    "inertia": "mass_kg",
    "sensor_lowpass": "cutoff_Hz",
}
HIDDEN_CHOICES = (*MAIN_PARAMETER, "none")


@dataclass(frozen=True)
class GeneratedTrace:
    """A generated trace and the effect hidden in it (None: no effect)."""

    trace: Trace
    hidden: fx.Effect | None
    force_kind: str


def draw_effect(
    name: str, rng: np.random.Generator, t: FloatArray, v: FloatArray, level: float
) -> fx.Effect | None:
    """One effect of the catalogue with parameters drawn in a range that matters."""
    vmax = float(np.max(np.abs(v)))
    amax = float(np.max(np.abs(np.gradient(v, t))))
    u = rng.uniform
    if name == "none":
        return None
    effects: dict[str, fx.Effect] = {
        "viscous": fx.Viscous(u(0.15, 0.4) * level / vmax),
        "stribeck": fx.Stribeck(u(1.3, 1.8), u(0.05, 0.2) * vmax),
        "dwell_time": fx.DwellTime(gain := u(0.15, 0.3), u(0.01, 0.05), gain),
        "position_ripple": fx.PositionRipple(
            u(0.08, 0.2) * level, u(0.5e-3, 3e-3), u(-math.pi, math.pi)
        ),
        "offset": fx.Offset(float(rng.choice([-1, 1])) * u(0.08, 0.2) * level),
        "reversal_transient": fx.ReversalTransient(u(0.15, 0.3) * level, u(20e-6, 80e-6)),
        "drift": fx.Drift(u(0.15, 0.3), u(0.1, 0.4) * float(t[-1])),
        "inertia": fx.Inertia(u(0.3, 0.6) * level / amax),
        "sensor_lowpass": fx.SensorLowpass(u(5.0, 25.0), int(rng.integers(1, 3))),
    }
    return effects[name]


# Below this speed the truth stands still (its trajectories stop exactly).
TRUTH_STANDSTILL_SPEED_M_S = 1e-9


def generate(
    hidden: str, seed: int, scale: float = 0.5, sample_rate_Hz: float = 1000.0
) -> GeneratedTrace:
    """A friction-force trace of the truth GMS with the effect ``hidden`` (or "none")."""
    if hidden not in HIDDEN_CHOICES:
        raise ValueError(f"unknown hidden effect {hidden!r}")
    rng = np.random.default_rng(seed)
    truth = tracegen.truth(scale=scale, sample_rate_Hz=sample_rate_Hz)
    t, x, v = truth.time_s, truth.position_m, truth.velocity_m_s
    effect = draw_effect(hidden, rng, t, v, truth.sliding_force_N)
    # the truth rests while it does not move (not below a speed threshold of the
    # diagnosis's choosing: a break-away starts with the first nanometre)
    ctx = fx.Context.along(
        t, x, v, truth.acceleration_m_s2, truth.gms_force_N, TRUTH_STANDSTILL_SPEED_M_S
    )
    ctx = dataclasses.replace(ctx, gms=tracegen.TRUTH_GMS)
    force = fx.apply_extensions([] if effect is None else [effect], ctx)
    force, measured_x = tracegen.measure(force, x, truth.sliding_force_N, rng)
    trace = Trace(
        source=f"demo-trace:{hidden}:{seed}", time_s=t, position_m=measured_x, force_N=force
    )
    return GeneratedTrace(trace, effect, "friction")


def scaled_table_trace(
    table: GmsParams, level: float, presliding: float, seed: int, scale: float = 0.5
) -> Trace:
    """A friction trace of ``table`` with its level and presliding length scaled, over the
    identification profile, with 1 % noise and 0.1 um position steps: a machine whose
    guides match the catalogue table up to the factors a calibration must find."""
    truth = tracegen.truth(scaled(table, level, presliding), scale)
    noise = 0.01 * truth.sliding_force_N
    force = truth.gms_force_N + np.random.default_rng(seed).normal(0.0, noise, len(truth.time_s))
    x = np.round(truth.position_m, 7)
    return Trace(source="scaled table", time_s=truth.time_s, position_m=x, force_N=force)


def register(subparsers: Any) -> None:
    """Add ``demo-trace`` to the CLI."""
    p = subparsers.add_parser(
        "demo-trace",
        help="write a measured-like friction trace (simulated, optionally with one "
        "catalogue effect hidden in it) as canonical CSV",
        description=(
            "Simulate a test-stand friction trace without hardware: a GMS truth along the "
            "identification profile (gms-comp profile), one catalogue effect if asked, 1 %% "
            "sensor noise, a 0.1 um encoder and a 12-bit force ADC. The CSV has the columns "
            "time_s, position_m, force_N that gms-comp diagnose reads."
        ),
    )
    p.add_argument("out", type=output_file, metavar="OUT.csv", help="CSV file to write")
    p.add_argument(
        "--effect",
        choices=HIDDEN_CHOICES,
        default="none",
        help="the catalogue effect to hide in the trace (default: none)",
    )
    p.add_argument(
        "--seed",
        type=int_in_range(0, MAX_SEED),
        default=0,
        help=f"random seed, 0 to {MAX_SEED} (default 0)",
    )
    p.add_argument(
        "--scale",
        type=float,
        default=0.5,
        choices=(0.25, 0.5, 1.0, 2.0),
        help="length of the profile (0.5: about 20 000 samples at 1 kHz)",
    )
    p.add_argument("--json", action="store_true", help="print the result as JSON on stdout")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Write the trace and say what it holds."""
    g = generate(args.effect, args.seed, args.scale)
    tr = g.trace
    buf = io.StringIO()
    np.savetxt(
        buf, np.column_stack([tr.time_s, tr.position_m, tr.force_N]), delimiter=",",
        comments="", fmt="%.12g", header="time_s,position_m,force_N",
    )  # fmt: skip
    write_text(args.out, buf.getvalue())
    doc: dict[str, Any] = {
        "file": str(args.out),
        "samples": len(tr),
        "duration_s": float(tr.time_s[-1] - tr.time_s[0]),
        "hidden": fx.effect_to_dict(g.hidden) if g.hidden else {"effect": "none"},
    }
    if args.json:
        sys.stdout.write(json.dumps(doc, indent=2) + "\n")
        print(f"wrote {args.out}", file=sys.stderr)
        return 0
    what = doc["hidden"]
    params = ", ".join(f"{k} = {v:.4g}" for k, v in what.get("parameters", {}).items())
    print(
        f"simulated {doc['samples']} samples ({doc['duration_s']:.1f} s) of friction force, "
        f"hidden effect: {what['effect']}{f' ({params})' if params else ''}"
    )
    print(f"wrote {args.out}")
    return 0
