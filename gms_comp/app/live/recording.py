"""Recording the axis on the bus into a trace the diagnosis reads, with its sidecar.

With an NC on the bus the recording only listens (one row per SYNC of the NC); without
one it drives the axis itself along the identification profile (``gms-comp profile``):
NMT start, the CiA 402 enable sequence, cyclic synchronous position as SYNC master, the
axis disabled at the end (:class:`~firmware_bridge.profiles.cia402.motion.NcProgram`).
Rows come from the drive's TPDOs (:mod:`firmware_bridge.profiles.cia402.recorder`): a
lost or late one leaves NaN in its row, counted in the sidecar, never interpolated.

The force column is the motor force, ``force_N = k_f * current_actual`` with the force
constant of ``[plant]`` (the sidecar states it): a drive force, inertia included, which
the diagnosis reads as such (it fits the moving mass beside the friction, on the
acceleration of the measured position). Subtracting the inertia of the commanded motion
instead left a tenth to a quarter of the mass in the residual: the target's acceleration
is not the axis's within the loop's small, fast following error.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, cast

import can
import numpy as np

from firmware_bridge.bus import open_bus
from firmware_bridge.faults import Fault, FaultyReceiver
from firmware_bridge.profiles.cia402.codec import NMT_START, PDOS
from firmware_bridge.profiles.cia402.motion import NcProgram
from firmware_bridge.profiles.cia402.recorder import Recorder, Recording
from firmware_bridge.profiles.cia402.tx import Cia402Tx
from firmware_bridge.realtime import stream_on
from firmware_bridge.session import DriveFactory, Rig
from firmware_bridge.settings import CanConfig
from gms_comp.arrays import FloatArray
from gms_comp.atomic import write_text
from gms_comp.errors import BusError
from gms_comp.measured.traces import Trace, write_trace
from sim.plant import PlantConfig
from sim.tracegen import identification_profile

NC_LISTEN_S = 0.3  # a SYNC within this long means an NC runs the bus
PROFILE_MAX_ACCELERATION_M_S2 = 0.05
"""The identification profile on a drive: moves stretched below this acceleration, so the
inertia in the current stays small beside the friction (30 kg: 1.5 N against 11 N)."""
HOLD_CYCLES = 200


@dataclass(frozen=True)
class RecordedTrace:
    """A recording turned into a trace, and what the sidecar says of it."""

    trace: Trace
    sidecar: dict[str, Any]


def nc_on_bus(cfg: CanConfig, listen_s: float = NC_LISTEN_S) -> bool:
    """Whether another node produces SYNC on the channel."""
    tx = Cia402Tx(replace(cfg, sync_master=False))
    deadline = time.monotonic() + listen_s
    with open_bus(cfg) as bus:
        while (remaining := deadline - time.monotonic()) > 0:
            msg = bus.recv(timeout=remaining)
            if msg is not None and msg.arbitration_id == tx.codec.sync_cob_id:
                return True
    return False


def profile_targets(period_s: float, scale: float) -> FloatArray:
    """The identification profile as targets one per bus cycle, from rest at 0, its moves
    gentle enough for a drive's current (:data:`PROFILE_MAX_ACCELERATION_M_S2`)."""
    _, x, _ = identification_profile(1.0 / period_s, scale, PROFILE_MAX_ACCELERATION_M_S2)
    return x


Feedforward = Callable[[NcProgram], "float | None"]
"""The feedforward current for the cycle about to be sent, from the NC's program."""


def drive_and_record(
    cfg: CanConfig,
    targets: Sequence[float],
    faults: Sequence[Fault] = (),
    seed: int = 0,
    stop_request: threading.Event | None = None,
    feedforward: Feedforward | None = None,
    drive: DriveFactory | None = None,
    prepare: Callable[[Rig], None] | None = None,
) -> tuple[Recording, dict[str, Any]]:
    """Drive the axis along ``targets`` as NC and SYNC master and record it; with
    ``feedforward``, the torque offset of each cycle from it (else 0 A).

    The drive is on the bus, and the stream runs in real time; or, with ``drive``, the
    drive is built in and stepped in the same thread, one cycle after the other (exact
    and repeatable, as the simulated closed loop runs). Returns the recording and the
    stream's report. A stop request ends the program early, the axis disabled.
    ``prepare`` runs on the open rig first (a table download for the drive's own observer).
    """
    cfg = replace(cfg, profile="cia402", sync_master=True)
    with Rig(cfg, faults, seed, builtin_drive=drive is not None, drive=drive) as rig:
        tx = cast(Cia402Tx, rig.tx)
        if prepare is not None:
            prepare(rig)
        rig.streamer.bus.send(_nmt_start(cfg))
        tx.program = NcProgram(list(targets), tx.observed.unit_m, HOLD_CYCLES)
        tx.recorder = Recorder(tx.codec, tx.observed.unit_m, cfg.rated_current_A)
        duration = (len(targets) + HOLD_CYCLES + 60) * cfg.cycle_period_s
        program = tx.program

        def source(t_s: float) -> float | None:
            return 0.0 if feedforward is None else feedforward(program)

        if drive is None:
            report = stream_on(rig, source, duration, stop_request=stop_request)
        else:
            report = _stepped(rig, source, round(duration / cfg.cycle_period_s))
        if tx.program.phase.value == "failed":
            raise BusError(
                f"drive node {cfg.drive_node_id} did not follow the NC's program "
                f"(state {tx.observed.state}): is it enabled, in CSP mode, without a fault?"
            )
        return tx.recorder.finish(), report


def _stepped(rig: Rig, source: Callable[[float], float | None], cycles: int) -> dict[str, Any]:
    """The stream of :func:`~firmware_bridge.realtime.stream_on`, one cycle per step."""
    period = rig.cfg.cycle_period_s
    cycle = 0
    while cycle < cycles or rig.streamer.shaper.value_raw != 0:
        rig.step(cycle, source(cycle * period) if cycle < cycles else None)
        cycle += 1
    end = rig.stop(cycle, cycle * period)
    rig.drive.step(cycle * period)
    return {**rig.report(), "cycles": cycle, "end_of_stream": end}


def listen_and_record(
    cfg: CanConfig, duration_s: float, faults: Sequence[Fault] = (), seed: int = 0
) -> Recording:
    """Record an axis an NC drives: one row per SYNC seen, for ``duration_s``."""
    tx = Cia402Tx(replace(cfg, profile="cia402", sync_master=False))
    recorder = Recorder(tx.codec, tx.observed.unit_m, cfg.rated_current_A)
    tx.recorder = recorder
    deadline = time.monotonic() + duration_s
    with open_bus(cfg) as raw:
        bus = FaultyReceiver(raw, tuple(faults), frozenset({tx.codec.status_cob_id,
                             tx.codec.motion_cob_id}), cfg.cycle_period_s, seed)  # fmt: skip
        while (remaining := deadline - time.monotonic()) > 0:
            msg = bus.recv(timeout=min(remaining, 0.05))
            if msg is not None:
                tx.on_reply(msg, time.time())
    return recorder.finish()


def reversals(target: FloatArray) -> list[int]:
    """Rows where the target's motion changes direction (rows without a target skipped)."""
    rows = np.flatnonzero(np.isfinite(target))
    step = np.diff(target[rows])
    moving = np.flatnonzero(step != 0.0)
    signs = np.sign(step[moving])
    return [int(rows[moving[i + 1]]) for i in np.flatnonzero(signs[1:] != signs[:-1])]


def to_trace(
    recording: Recording, cfg: CanConfig, plant: PlantConfig, source: str
) -> RecordedTrace:
    """The rows as a trace (force from current, less the target's inertia) and the sidecar."""
    period = cfg.cycle_period_s
    n = recording.span
    first = recording.slots[0] if recording.slots else 0
    target = recording.column("reference_position_m")
    current = recording.column("current_A")
    force = plant.force_constant_N_per_A * current
    trace = Trace(
        source=source,
        time_s=(first + np.arange(n)) * period,
        position_m=recording.column("position_m"),
        force_N=force,
        velocity_m_s=recording.column("velocity_m_s"),
        reference_position_m=target,
        current_A=current,
        force_kind="drive",
    )
    missing = ~(np.isfinite(trace.position_m) & np.isfinite(force))
    sidecar = {
        "source": source,
        "force_kind": "drive",  # diagnose reads it: the moving mass is fitted
        "drive": {
            "node_id": cfg.drive_node_id,
            "interface": cfg.interface,
            "channel": cfg.channel,
        },
        "cycle_period_s": period,
        "samples": n,
        "samples_missing": int(missing.sum()),
        "syncs_skipped": n - len(recording.rows),
        "lost": dict(recording.lost),
        "late": recording.late,
        "scaling": {
            "position_unit_m": recording.unit_m,
            "rated_current_A": recording.rated_current_A,
            "force_constant_N_per_A": plant.force_constant_N_per_A,
            "force_N": "force_constant * current_A (a drive force: inertia included)",
        },
        "pdo_mapping": {
            f"0x{pdo.comm:04X}": [f"0x{i:04X}:{bits}" for i, bits in pdo.objects] for pdo in PDOS
        },
    }
    return RecordedTrace(trace, sidecar)


def write_recording(recorded: RecordedTrace, out: Path) -> list[Path]:
    """The trace CSV and its JSON sidecar beside it (``OUT.csv.json``). A missing sample's
    row is left out, so the reader sees it (and says how it reads around it, or refuses a
    gap): nothing is interpolated here."""
    write_trace(out, present_samples(recorded.trace))
    sidecar = out.with_suffix(out.suffix + ".json")
    return [out, write_text(sidecar, json.dumps(recorded.sidecar, indent=2) + "\n")]


def present_samples(trace: Trace) -> Trace:
    """The trace without its missing samples (rows the bus lost)."""
    keep = np.isfinite(trace.position_m) & np.isfinite(trace.force_N)
    for name in ("velocity_m_s", "reference_position_m", "current_A"):
        column = getattr(trace, name)
        if column is not None:
            keep &= np.isfinite(column)
    if keep.all():
        return trace
    idx = np.flatnonzero(keep)

    def cut(a: FloatArray | None) -> FloatArray | None:
        return None if a is None else a[idx]

    return Trace(trace.source, trace.time_s[idx], trace.position_m[idx], trace.force_N[idx],
                 cut(trace.velocity_m_s), cut(trace.reference_position_m), cut(trace.current_A),
                 None, trace.force_kind)  # fmt: skip


def _nmt_start(cfg: CanConfig) -> can.Message:
    return can.Message(arbitration_id=0, data=bytes([NMT_START, cfg.drive_node_id]),
                       is_extended_id=False)  # fmt: skip
