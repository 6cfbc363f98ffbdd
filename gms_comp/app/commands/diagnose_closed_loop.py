"""Closed-loop gain of a diagnosis: the compensator with the extended model against the
one with the baseline model, on a simulated axis whose friction holds the found effects.

The plant's friction truth is the extended model the diagnosis wrote: its GMS runs in the
axis's compiled truth, its physical effects (those not ``measurement_only``) act as a
force disturbance entering with the drive current (:class:`EffectDisturbance`), evaluated
along the reference (the following error is micrometres, far below the effects'
length scales: ripple wavelengths, transient lengths). Both compensators see the same
plant; only their table differs: the baseline GMS alone, or the extended table.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.gms import GmsParams, GmsStream, simulate
from gms_comp.measured.diagnosis.run import Diagnosis
from gms_comp.runtime import effects as fx
from gms_comp.tables.table import Extension, Fidelity, GmsTable
from sim.link import DirectLink, FeedforwardLink
from sim.scenarios import Physics, Scenario, build_reference, load_scenario, run_strategies, score


class EffectDisturbance:
    """A :class:`~sim.link.FeedforwardLink` that delivers the compensator's current through
    ``link`` and adds the current of an extra resisting force (``force_N[cycle]``)."""

    def __init__(self, link: FeedforwardLink, force_N: FloatArray, force_constant_N_per_A: float):
        self.link = link
        self.current_A = -np.asarray(force_N) / force_constant_N_per_A

    def transfer(self, cycle: int, current_A: float) -> float:
        """The link's current for ``cycle`` plus the diagnosed effects' current."""
        extra = float(self.current_A[min(cycle, self.current_A.size - 1)])
        return self.link.transfer(cycle, current_A) + extra


def _effect_force(
    s: Scenario, gms: GmsParams, effects: list[fx.Effect], context: dict[str, float]
) -> FloatArray:
    """The physical effects' force along the reference (extended minus plain GMS), the path
    seen with the diagnosis's standstill speed, reversal deadband and rest band
    (``context``). It is the plant's force, so its reversals are dated in hindsight, from
    the turning point, as the diagnosis fitted them: the contact turns when the motion
    does. The compensator's stream learns of a reversal only once the retreat passes the
    deadband (up to a few samples later); dated causally here too, the plant's transient
    would wait for it, and the compensator would match the plant's timing by
    construction."""
    ref = build_reference(s)
    force = simulate(gms, ref.position_m, ref.velocity_m_s)[0]
    # absent keys: the defaults, as the observer reads them
    ctx = fx.Context.of(
        ref.kinematics, force,
        context.get("standstill_speed_m_s", fx.DEFAULT_STANDSTILL_SPEED_M_S),
        context.get("reversal_deadband_m", 0.0), context.get("rest_band_m", 0.0),
        hindsight=True,
    )  # fmt: skip
    ctx = dataclasses.replace(ctx, gms=gms)
    return fx.apply_extensions(effects, ctx) - force


def closed_loop_gain(
    result: Diagnosis, scenario_path: str | Path | None = None
) -> dict[str, dict[str, float | None]]:
    """Peak reversal error and RMS error (m) with the baseline and the extended compensator.

    The scenario (default: the packaged Table 1 config's circularity test) keeps its
    trajectory, axis and controller; its friction is replaced by one copy of the
    diagnosed model (``ball_set_count`` 1, level scale 1).
    """
    s = load_scenario(scenario_path)
    s = dataclasses.replace(
        s,
        plant=dataclasses.replace(s.plant, ball_set_count=1.0),
        compensator=dataclasses.replace(s.compensator, friction_level_scale=1.0, table_path=""),
    )
    physical = [e for e in result.extensions if not e.measurement_only]
    disturbance = _effect_force(s, result.gms, physical, result.extension_context)
    base = result.base_gms
    level = max(float(result.baseline["sliding_force_N"]), 1e-12)
    tables = {
        "baseline": GmsTable(
            base, "diagnosis baseline", "", Fidelity(result.baseline_rms_N / level, np.nan)
        ),
        "extended": GmsTable(
            result.gms, "diagnosis extended", "", Fidelity(result.extended_rms_N / level, np.nan),
            extensions=tuple(Extension(e.name, e.parameters()) for e in physical),
            extension_context=result.extension_context or None,
        ),
    }  # fmt: skip
    kf = s.plant.force_constant_N_per_A
    out: dict[str, dict[str, float | None]] = {}
    for name, table in tables.items():

        def table_of(_s: Scenario, table: GmsTable = table) -> GmsTable:
            return table

        physics = Physics(truth=lambda _b: GmsStream(result.gms), table=table_of)
        run = run_strategies(
            s, ["gms"], physics, link=lambda d: EffectDisturbance(DirectLink(d), disturbance, kf)
        )["gms"]
        scores = score(run, s.scenario)
        out[name] = {k: scores[k] for k in ("peak_reversal_error_m", "rms_error_m")}
    return out
