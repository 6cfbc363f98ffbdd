"""The compensator on a replayed axis: no feedforward, the reference model, the GMS observer.

The record's own controller runs the axis with a chosen friction (the extended table's,
say); each feedforward travels its link (CAN, as ``simulate --via-can``) and is scored by
the following error and by the friction's share of it.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Mapping

import numpy as np
from numpy.typing import NDArray

from gms_comp.app.replay import BENCHMARK_REFERENCE, Record
from gms_comp.arrays import FloatArray
from gms_comp.runtime.observer import CompensatorConfig, FrictionObserver
from gms_comp.tables.table import GmsTable
from sim.link import FeedforwardLink
from sim.position_loop import LoopRun, RigidAxisModel, simulate_loop
from sim.strategies import CoulombViscous

COMPENSATION_REVERSAL_WINDOW_S = 0.15  # as [scenario] reversal_window_s


def reference_velocity(record: Record) -> FloatArray:
    """The reference's velocity (central differences over the replay's cycles)."""
    return np.asarray(np.gradient(record.reference_m, record.loop.period_s), dtype=np.float64)


def feedforward_sequence(
    record: Record, observer: FrictionObserver | None, link: FeedforwardLink, look_ahead: int
) -> FloatArray:
    """The observer's output per cycle (command units), fed with the reference
    ``look_ahead`` cycles ahead and carried by ``link``: it does not depend on the
    loop, so it is computed before the compiled run."""
    n = record.reference_m.size
    out = np.zeros(n)
    if observer is None:
        return out
    observer.reset()
    ref, vel = record.reference_m, reference_velocity(record)
    for k in range(n):
        j = min(k + look_ahead, n - 1)
        out[k] = link.transfer(k, observer.step(float(ref[j]), float(vel[j])))
    return out


def reference_reversals(record: Record) -> NDArray[np.intp]:
    """Cycles where the reference's velocity changes sign (through a stop or not)."""
    vel = reference_velocity(record)
    moving = np.flatnonzero(np.abs(vel) > 1e-6)
    return moving[1:][np.sign(vel[moving][1:]) != np.sign(vel[moving][:-1])]


def following_scores(record: Record, run: LoopRun, frictionless: LoopRun) -> dict[str, float]:
    """Following error (reference minus simulated position): RMS, peak, and the peak
    within 150 ms after each reversal of the reference; the same for the friction's
    share of it (the position of the same loop on a frictionless axis minus this one's).
    """
    out = {}
    errors = {
        "following": record.reference_m - run.position_m,
        "friction": frictionless.position_m - run.position_m,
    }
    window = max(1, round(COMPENSATION_REVERSAL_WINDOW_S / record.loop.period_s))
    for key, error in errors.items():
        peaks = [float(np.max(np.abs(error[i : i + window]))) for i in reference_reversals(record)]
        out[f"rms_{key}_error_m"] = float(np.sqrt(np.mean(error**2)))
        out[f"peak_{key}_error_m"] = float(np.max(np.abs(error)))
        out[f"peak_reversal_{key}_error_m"] = max(peaks, default=math.nan)
    return out


def compensation(
    record: Record,
    plant: RigidAxisModel,
    table: GmsTable,
    links: Callable[[], contextlib.AbstractContextManager[FeedforwardLink]],
    config: CompensatorConfig | None = None,
    reference_parameters: Mapping[str, float] = BENCHMARK_REFERENCE,
) -> tuple[LoopRun, dict[str, tuple[LoopRun, dict[str, float]]]]:
    """The axis with ``plant`` as its friction under the record's controller, with no
    feedforward, the reference model's Coulomb + viscous, and the GMS observer of
    ``table``; ``links()`` opens the path each feedforward travels. Returns the run of
    the frictionless axis and each feedforward's run and scores."""
    cfg = config or CompensatorConfig()
    loop = record.loop
    coulomb = CoulombViscous(
        reference_parameters["Fc_N"],
        reference_parameters["Fv_Ns_per_m"],
        cfg.coulomb_velocity_band_m_s,
    )
    observers: dict[str, FrictionObserver | None] = {
        "none": None,
        "reference": FrictionObserver(coulomb, loop.drive_gain_N, loop.period_s, 1.0, cfg),
        "gms": FrictionObserver(table, loop.drive_gain_N, loop.period_s, 1.0, cfg),
    }
    ideal = simulate_loop(
        loop, RigidAxisModel(plant.mass_kg, drive_lag_s=plant.drive_lag_s), record.reference_m,
        None, record.disturbance,
    )  # fmt: skip
    out = {}
    for name, observer in observers.items():
        with links() as link:
            ff = feedforward_sequence(record, observer, link, cfg.look_ahead_cycles)
        run = simulate_loop(loop, plant, record.reference_m, ff, record.disturbance)
        out[name] = (run, following_scores(record, run, ideal))
    return ideal, out
