"""Replay a measured closed-loop run in the simulated axis (an output-error test).

The record's own loop (:class:`sim.position_loop.PositionLoop`: for EMPS its ``kp``,
``kv``, ``gtau``, the filtered-derivative velocity feedback, the one-sample delay, the
+-10 V saturation, the PULSES record's pulses after the saturation) runs the record's
reference on a rigid axis whose friction is a chosen model; the simulated position,
velocity, acceleration and drive force are compared with the measurement as the EMPS
benchmark does (Janot, Gautier, Brunot 2019, §3.5, Simulation_EMPS.m): relative
errors ``100 ||y - y_sim|| / ||y||`` after the first 49 samples, with the measured
velocity and acceleration from the zero-phase 100 Hz Butterworth of the position.

Models: the benchmark's reference IDIM-LS model (its published parameters), a GMS table
(``diagnose --table`` writes the extended one), or the baseline of a ``diagnose`` JSON.

Two timings of the loop (``loop``):

- ``"benchmark"`` (default): the benchmark's Simulink loop, a one-sample Unit Delay
  between the controller and the drive and no other drive dynamics; the published
  reference rows are reproduced on it. A table's ``drive_lag`` stays out of the plant
  (the delay stands in for it: both together destabilise the replay).
- ``"record"``: the timing the record itself shows. The recorded EMPS command is the
  control law of the same sample's position (0.0037 V RMS with no delay, 0.054 V with
  one), and the drive force acts in the sample it was commanded in (the benchmark's
  reference model, fitted to the force against the centred acceleration, fits it with
  the force of the same sample and worse with the next one's). So the command acts in
  its own cycle, held over it, and the axis force follows it through the drive lag a
  table's ``drive_lag`` identified, less half a cycle (the reference model has none:
  IDIM-LS fits none). The diagnosis fits the command against the centred acceleration
  of the sampled position, so it reads the half cycle by which a held command acts after
  its sample as lag (a lag-free held command, replayed and diagnosed, gives 0.47 ms at
  1 kHz); the replay holds the command itself, so only the rest is the drive's.

``gms-comp replay`` uses ``"record"`` with the record's own time stamps (``time_base =
"data"``) by default and prints the paper's rows, reproduced on the benchmark's timing,
beside: the Simulink time base's cycles of ``t[9] - t[8]`` drift 0.4 ms from the record's
clock by the end of DATA_EMPS, which alone puts a +-20 um position error at constant speed
into any model's replay.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
import scipy.io
from numpy.typing import NDArray
from scipy import signal

from gms_comp.arrays import FloatArray
from gms_comp.config import parse_section, read_toml
from gms_comp.errors import GmsCompError, TableError
from gms_comp.gms import GmsParams
from gms_comp.measured.traces import load_trace
from gms_comp.runtime.effects import check_extensions
from gms_comp.tables.table import (
    MAX_FORCE_N,
    MAX_SLIP_LEVEL,
    MAX_STIFFNESS_N_PER_M,
    MAX_TRANSITION_EXPONENT,
    MAX_TRANSITION_TAIL,
    MAX_TRANSITION_VELOCITY_M_S,
    GmsTable,
    table_from_dict,
)
from gms_comp.validation import (
    MAX_TABLE_BYTES,
    MAX_TABLE_ELEMENTS,
    InputError,
    JsonReader,
    check_count,
    parse_json,
    read_text,
    shown,
)
from sim.controller import ControllerConfig
from sim.position_loop import LoopRun, PositionLoop, RigidAxisModel, simulate_loop

TimeBase = Literal["simulink", "data"]
LoopTiming = Literal["benchmark", "record"]
# Cycles between the controller's output and the drive: the benchmark's Simulink Unit
# Delay, and the record's own (the recorded command acts in the cycle it is computed in).
COMMAND_DELAY_CYCLES: dict[str, int] = {"benchmark": 1, "record": 0}

# The benchmark's reference model (EMPS_Description.pdf §3.4, hard-coded in its
# Simulation_EMPS.m): M [kg], Fv [N s/m], Fc [N], offset [N].
BENCHMARK_REFERENCE = {
    "M_kg": 95.1089,
    "Fv_Ns_per_m": 203.5034,
    "Fc_N": 20.3935,
    "offset_N": -3.1648,
}
DROPPED_SAMPLES = 49  # MATLAB n_border = 50, 1-based
FILTER_CUTOFF_HZ = 100.0
REVERSAL_WINDOW_S = 0.025  # +-25 ms around a velocity reversal
STANDSTILL_SPEED_M_S = 2e-3
STEADY_ACCELERATION_M_S2 = 0.05
# A retreat the simulated axis must make before the reversal transient starts again:
# the noise-free simulated axis creeps back by fractions of a micrometre when it stops
# and goes on in the same direction, which the measured axis (whose reversals the
# transient was fitted on, with a deadband of 0.6 encoder steps) does not. Chosen on
# DATA_EMPS (force error 8.0 % with none, 4.3 % from 3 um to 10 um).
REVERSAL_DEADBAND_M = 3e-6
#: Reversal deadband of a replay (``--reversal-deadband``), m.
MAX_REVERSAL_DEADBAND_M = 1e-2
#: Mass of a replayed axis (a diagnosis baseline's, or a table's inertia), kg.
MAX_AXIS_MASS_KG = 1e5

# The measurement chain's effects (the catalogue's measurement_only ones): the rigid axis
# takes its mass from ``inertia`` and leaves the others out, as the observer does, but for
# ``drive_lag`` on the record's loop (the axis force lags the command there).
MEASUREMENT_ONLY = frozenset({"sensor_lowpass", "drive_lag"})


@dataclass(frozen=True)
class Record:
    """A measured closed-loop run, on the time base of the replay."""

    source: str
    time_s: FloatArray  # the record's own time stamps
    position_m: FloatArray
    force_N: FloatArray  # the drive force, drive gain times the recorded command
    reference_m: FloatArray  # per replay cycle
    loop: PositionLoop
    disturbance: tuple[FloatArray, FloatArray] | None  # (time_s, command units)


def load_record(
    path: str | Path,
    controller: ControllerConfig | None = None,
    time_base: TimeBase = "simulink",
    loop: LoopTiming = "benchmark",
) -> Record:
    """Read a closed-loop record: an EMPS ``.mat`` (the loop from its ``kp``, ``kv``,
    ``gtau``, its command delay from ``loop``: :data:`COMMAND_DELAY_CYCLES`), or any
    trace with a ``reference_position_m`` column and a
    ``[controller] structure = "position_velocity"`` section describing its loop (its
    ``command_delay_cycles`` whatever ``loop``).

    ``time_base = "simulink"`` replays as the benchmark's Simulink model does: cycles
    of ``t[9] - t[8]`` from 0, the reference interpolated at them; ``"data"``: one cycle
    per recorded sample, of the mean sampling interval.
    """
    trace = load_trace(path)
    if trace.reference_position_m is None:
        raise InputError(str(path), "reference_position_m", "a replay needs the reference")
    variables = _mat_variables(Path(path))
    cfg = controller or ControllerConfig(structure="position_velocity")
    if controller is None and not {"kp", "kv", "gtau"} <= variables.keys():
        raise InputError(
            str(path), "controller", "no loop gains in the record: give a config whose "
            '[controller] has structure = "position_velocity" and its gains',
        )  # fmt: skip
    if controller is not None and controller.structure != "position_velocity":
        raise InputError(str(path), "controller.structure", 'must be "position_velocity"')
    t = np.asarray(trace.time_s, float)
    period = float(t[9] - t[8]) if time_base == "simulink" else trace.sample_time_s
    if controller is None:
        cfg = replace(
            cfg,
            servo_rate_Hz=1.0 / period,
            kp_per_s=float(variables["kp"][0]),
            kv_command_s_per_m=float(variables["kv"][0]),
            drive_gain_N_per_command=float(variables["gtau"][0]),
            command_delay_cycles=COMMAND_DELAY_CYCLES[loop],
        )
    position_loop = replace(PositionLoop.from_config(cfg), period_s=period)
    cycles = np.arange(t.size) * period + t[0]
    reference = np.interp(cycles, t, trace.reference_position_m) if time_base == "simulink" else (
        np.asarray(trace.reference_position_m, float)
    )  # fmt: skip
    pulses = variables.get("pulses_N")
    disturbance = (t - t[0], pulses) if pulses is not None and pulses.size == t.size else None
    return Record(
        str(path), t, np.asarray(trace.position_m, float), np.asarray(trace.force_N, float),
        reference, position_loop, disturbance,
    )  # fmt: skip


def parse_controller(path: str | Path) -> ControllerConfig:
    """The ``[controller]`` section of a config file."""
    return parse_section(read_toml(path), path, "controller", ControllerConfig)


def _mat_variables(path: Path) -> dict[str, FloatArray]:
    """Numeric variables of a .mat record (none for other files)."""
    if path.suffix.lower() != ".mat":
        return {}
    raw = scipy.io.loadmat(str(path))
    return {
        k: np.asarray(v, float).ravel()
        for k, v in raw.items()
        if not k.startswith("__") and isinstance(v, np.ndarray) and v.dtype.kind in "biuf"
    }


# --- models -------------------------------------------------------------------------------


def reference_model(parameters: Mapping[str, float] = BENCHMARK_REFERENCE) -> RigidAxisModel:
    """The benchmark's model: ``M ddq + Fv dq + Fc sign(dq) + offset``."""
    fc, fv = parameters["Fc_N"], parameters["Fv_Ns_per_m"]
    return RigidAxisModel(parameters["M_kg"], parameters["offset_N"], fc, fc, fv, fv)


def table_axis_model(
    table: GmsTable,
    mass_kg: float,
    where: str,
    reversal_deadband_m: float = REVERSAL_DEADBAND_M,
    held_period_s: float | None = None,
) -> RigidAxisModel:
    """The rigid axis of a GMS table and its extensions (``mass_kg`` unless the table
    has an ``inertia`` extension). Given the period over which the loop holds its
    command (the record's loop), the table's ``drive_lag`` less half that period makes
    the axis force a first-order lag of the command; else the lag stays out with the
    other measurement-chain effects (the benchmark's loop)."""
    fields: dict[str, Any] = {
        "mass_kg": mass_kg,
        "gms": table.params,
        "reversal_deadband_m": reversal_deadband_m,
    }
    viscous = table.params.viscous_Ns_per_m
    asymmetry = 0.0
    for ext in table.extensions:
        p = ext.parameters
        if ext.effect == "viscous":
            viscous += p["c_Ns_per_m"]
        elif ext.effect == "direction_asymmetry":
            asymmetry += p["c_diff_Ns_per_m"]
        elif ext.effect == "inertia":
            if not 0 < p["mass_kg"] <= MAX_AXIS_MASS_KG:
                raise InputError(
                    where,
                    f"extensions.{table.extensions.index(ext)}.parameters.mass_kg",
                    f"the replayed axis needs a mass in (0, {MAX_AXIS_MASS_KG:g}] kg, "
                    f"got {shown(p['mass_kg'])}",
                )
            fields["mass_kg"] = p["mass_kg"]
        elif ext.effect == "drive_lag" and held_period_s is not None:
            fields["drive_lag_s"] = max(p["lag_s"] - 0.5 * held_period_s, 0.0)
        elif ext.effect == "offset":
            fields["offset_N"] = p["offset_N"]
        elif ext.effect == "stribeck":
            fields.update(stribeck_ratio=p["ratio"], stribeck_velocity_m_s=p["v_s_m_per_s"])
        elif ext.effect == "reversal_transient":
            fields.update(reversal_amplitude_N=p["amplitude_N"], reversal_length_m=p["length_m"])
        elif ext.effect == "position_ripple":
            fields.update(
                ripple_amplitude_N=p["amplitude_N"],
                ripple_wavelength_m=p["wavelength_m"],
                ripple_phase_rad=p["phase_rad"],
            )
        elif ext.effect not in MEASUREMENT_ONLY:
            raise InputError(where, "extensions", f"effect {ext.effect!r} is not simulated")
    fields["viscous_pos_Ns_per_m"] = viscous + 0.5 * asymmetry
    fields["viscous_neg_Ns_per_m"] = viscous - 0.5 * asymmetry
    return RigidAxisModel(**fields)


def baseline_axis_model(baseline: Mapping[str, Any], where: str) -> RigidAxisModel:
    """The rigid axis of a diagnosis baseline (its free GMS, velocity level and mass; a
    baseline written before the level's transition was recorded has the defaults).

    Every field is checked as a table's same field is (:mod:`gms_comp.tables.table`'s
    bounds), the mass against :data:`MAX_AXIS_MASS_KG`."""
    r = JsonReader(where)
    key = "baseline"
    breakaway = r.vector(
        r.get(baseline, f"{key}.breakaway_m"), f"{key}.breakaway_m", None, True, 1.0
    )
    check_count(where, f"{key}.breakaway_m", len(breakaway), MAX_TABLE_ELEMENTS, "elements")
    limit = r.vector(
        r.get(baseline, f"{key}.limit_N"), f"{key}.limit_N", len(breakaway), False, MAX_FORCE_N
    )
    bounds = {
        "transition_velocity_m_s": MAX_TRANSITION_VELOCITY_M_S,
        "transition_exponent": MAX_TRANSITION_EXPONENT,
        "transition_tail": MAX_TRANSITION_TAIL,
    }
    level = {
        name: r.number(baseline, f"{key}.{name}", True, hi)
        for name, hi in bounds.items()
        if name in baseline and (name != "transition_tail" or baseline[name] is not None)
    }  # absent: the default; a null tail is the infinite one
    law = baseline.get("limit_follows_level", False)
    if not isinstance(law, bool):
        raise r.error(f"{key}.limit_follows_level", f"must be true or false, got {shown(law)}")
    keep = np.asarray(limit) > 0
    if not keep.any():
        raise r.error(f"{key}.limit_N", "no element has a limit > 0: there is no friction")
    k = np.asarray(limit)[keep] / np.asarray(breakaway)[keep]
    if np.any(k > MAX_STIFFNESS_N_PER_M):
        raise r.error(f"{key}.breakaway_m", f"stiffness above {MAX_STIFFNESS_N_PER_M:g} N/m")
    gms = GmsParams(
        k, np.asarray(limit)[keep],
        slip_level=r.number(baseline, f"{key}.slip_level", True, MAX_SLIP_LEVEL),
        limit_follows_level=law, **level,
    )  # fmt: skip
    if r.get(baseline, f"{key}.mass_kg") == 0:
        raise r.error(
            f"{key}.mass_kg", "is 0: the diagnosis of a friction-force trace has no mass to "
            "replay; give the diagnosis of a drive-force record (or a table)",
        )  # fmt: skip
    return RigidAxisModel(r.number(baseline, f"{key}.mass_kg", True, MAX_AXIS_MASS_KG), gms=gms)


@dataclass(frozen=True)
class ModelChoice:
    """A friction model to replay, its name and (for a table) the table."""

    name: str
    axis: RigidAxisModel
    table: GmsTable | None = None


def load_model(
    path: str | Path | None,
    reversal_deadband_m: float = REVERSAL_DEADBAND_M,
    held_period_s: float | None = None,
) -> ModelChoice:
    """``None``: the benchmark's reference; a GMS table file; a ``diagnose`` JSON (its
    baseline). ``held_period_s``: see :func:`table_axis_model` (the record's loop)."""
    if path is None:
        return ModelChoice("reference", reference_model())
    where = str(path)
    text = read_text(path, max_bytes=MAX_TABLE_BYTES, what="model file", error=TableError)
    doc = parse_json(text, where, error=TableError)
    mass = BENCHMARK_REFERENCE["M_kg"]
    if isinstance(doc, dict) and doc.get("format") == "gms-comp-table":
        table = table_from_dict(doc, where)
        check_extensions(table, where)
        name = "extended" if table.extensions else "table"
        axis = table_axis_model(table, mass, where, reversal_deadband_m, held_period_s)
        return ModelChoice(name, axis, table)
    if isinstance(doc, dict) and isinstance(doc.get("baseline"), dict):
        return ModelChoice("baseline", baseline_axis_model(doc["baseline"], where))
    raise InputError(where, "", "neither a GMS table nor a diagnose JSON with a baseline")


# --- scores -------------------------------------------------------------------------------


def measured_kinematics(record: Record) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Position, velocity and acceleration as the benchmark derives them: zero-phase
    4th-order Butterworth at 100 Hz (MATLAB's edge padding), central differences."""
    dt = float(np.mean(np.diff(record.time_s)))
    b, a = signal.butter(4, FILTER_CUTOFF_HZ * 2 * dt)
    q = signal.filtfilt(b, a, record.position_m, padlen=3 * (max(len(a), len(b)) - 1))
    v = np.gradient(q, dt)
    return q, v, np.gradient(v, dt)


def relative_errors_pct(record: Record, run: LoopRun) -> dict[str, float]:
    """The benchmark's relative errors, % (samples after the first 49)."""
    q, v, a = measured_kinematics(record)
    sim_force = record.loop.drive_gain_N * run.command
    pairs = {
        "position": (q, run.position_m),
        "velocity": (v, run.velocity_m_s),
        "acceleration": (a, run.acceleration_m_s2),
        "force": (record.force_N, sim_force),
    }
    s = slice(DROPPED_SAMPLES, None)
    return {
        k: float(100 * np.linalg.norm(m[s] - y[s]) / np.linalg.norm(m[s]))
        for k, (m, y) in pairs.items()
    }


def phases(record: Record) -> dict[str, NDArray[np.bool_]]:
    """Motion phases of the measured run: +-25 ms around each velocity reversal,
    standstill, constant speed by direction, acceleration (the rest)."""
    _, v, a = measured_kinematics(record)
    dt = float(np.mean(np.diff(record.time_s)))
    moving = np.abs(v) >= STANDSTILL_SPEED_M_S
    direction = np.sign(v)
    turns = np.flatnonzero((direction[1:] * direction[:-1] < 0) & moving[1:] & moving[:-1])
    # a reversal through a short stop: the sign before and after the stop differ
    idx = np.flatnonzero(moving)
    turns = np.union1d(turns, idx[1:][np.diff(direction[idx]) != 0])
    near = np.zeros(v.size, bool)
    half = round(REVERSAL_WINDOW_S / dt)
    for i in turns:
        near[max(0, i - half) : i + half + 1] = True
    steady = ~near & moving & (np.abs(a) < STEADY_ACCELERATION_M_S2)
    out = {
        "reversal": near,
        "standstill": ~near & ~moving,
        "constant_speed_pos": steady & (v > 0),
        "constant_speed_neg": steady & (v < 0),
    }
    out["acceleration"] = ~(near | ~moving | steady)
    return out


def phase_residuals(
    record: Record, run: LoopRun, masks: Mapping[str, NDArray[np.bool_]]
) -> dict[str, dict[str, float]]:
    """Force and position error RMS per phase (first 49 samples left out)."""
    force_error = record.force_N - record.loop.drive_gain_N * run.command
    position_error = record.position_m - run.position_m
    valid = np.arange(force_error.size) >= DROPPED_SAMPLES
    out = {}
    for name, mask in masks.items():
        m = mask & valid
        if not m.any():
            continue
        out[name] = {
            "fraction": float(m.mean()),
            "force_error_rms_N": float(np.sqrt(np.mean(force_error[m] ** 2))),
            "position_error_rms_m": float(np.sqrt(np.mean(position_error[m] ** 2))),
        }
    return out


def replay_scores(record: Record, run: LoopRun) -> dict[str, Any]:
    """The benchmark's relative errors and the position error of one replay."""
    error = record.position_m - run.position_m
    return {
        "relative_error_pct": relative_errors_pct(record, run),
        "position_error_rms_m": float(np.sqrt(np.mean(error**2))),
        "position_error_max_m": float(np.max(np.abs(error))),
        "force_error_rms_N": float(
            np.sqrt(np.mean((record.force_N - record.loop.drive_gain_N * run.command) ** 2))
        ),
    }


def replay(record: Record, model: RigidAxisModel) -> LoopRun:
    """Run the record's loop on its reference with ``model`` as the axis."""
    return simulate_loop(record.loop, model, record.reference_m, disturbance=record.disturbance)


def check_finite(run: LoopRun, where: str) -> None:
    """Refuse a replay that diverged."""
    if not (np.all(np.isfinite(run.position_m)) and math.isfinite(float(run.command[-1]))):
        raise GmsCompError(f"{where}: the replay diverged (non-finite position)")
