"""The simulated machine as a node of a CAN bus, and the NC that can drive it.

:func:`machine_on_bus` joins the simulated axis (:mod:`sim.machine`) to a CiA 402 drive
node of the transport (:class:`firmware_bridge.profiles.cia402.drive.Cia402Drive`, a
canopen LocalNode from the EDS) on any python-can interface; with a part program, an NC
(:class:`~firmware_bridge.profiles.cia402.nc.MotionNc`) on its own bus handle produces
SYNC and the CSP targets. Both run on their own clocks in threads, as separate devices
would; the same master code talks to them as to a real drive.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from firmware_bridge.bus import open_bus
from firmware_bridge.emulator import DriveEmulator
from firmware_bridge.profiles.cia402.codec import Cia402Codec, load_drive_od
from firmware_bridge.profiles.cia402.drive import Cia402Drive
from firmware_bridge.profiles.cia402.motion import NcProgram, Observed
from firmware_bridge.profiles.cia402.nc import MotionNc
from firmware_bridge.settings import CanConfig
from gms_comp.arrays import FloatArray
from gms_comp.errors import InputError
from gms_comp.measured.trace_csv import read_csv
from sim.machine import CspAxis, Machine
from sim.scenarios import build_reference

MAX_PROGRAM_SPEED_M_S = 5.0
"""A part program faster than this is no linear axis's (a unit slip: mm for m)."""
MAX_PROGRAM_S = 3600.0


@dataclass
class MachineNode:
    """The machine's drive, and its NC when it has a program, running on the bus."""

    drive: DriveEmulator
    node: Cia402Drive
    nc: MotionNc | None

    def status(self) -> dict[str, Any]:
        """The drive's status, its CiA 402 state, the axis and the NC's progress."""
        sample = self.node.sample
        drive = self.drive.status()
        drive["emcy"] = dict(Counter(drive["emcy"]))  # code -> times raised
        status: dict[str, Any] = {
            **drive,
            "statusword": f"0x{self.node.statusword:04X}",
            "position_m": None if sample is None else sample.position_m,
            "fault_code": f"0x{self.node.power.fault_code:04X}",
        }
        if self.nc is not None:
            status["nc"] = {
                "phase": self.nc.program.phase.value,
                "targets_sent": self.nc.program.index,
                "syncs_sent": self.nc.sent,
            }
        return status


@contextlib.contextmanager
def machine_on_bus(
    machine: Machine, cfg: CanConfig, program: FloatArray | None = None
) -> Iterator[MachineNode]:
    """The machine (and its NC with ``program``, targets one per bus cycle) on the bus of
    ``cfg``, running in threads until the block ends."""
    cfg = replace(cfg, profile="cia402", sync_master=program is None)
    stop = threading.Event()
    with contextlib.ExitStack() as stack:
        bus = stack.enter_context(open_bus(cfg))
        node = Cia402Drive(cfg, bus, CspAxis(machine, cfg.cycle_period_s))
        drive = DriveEmulator(cfg, bus, node)
        threads = [threading.Thread(target=drive.run, args=(stop, time.time), daemon=True)]
        nc = None
        if program is not None:
            nc_bus = stack.enter_context(open_bus(cfg))
            codec = Cia402Codec(cfg, load_drive_od(cfg.drive_node_id))
            nc = MotionNc(
                nc_bus,
                codec,
                cfg.cycle_period_s,
                NcProgram(list(program), node.unit_m, repeat=True),
                Observed(node.unit_m, cfg.rated_current_A),
            )
            threads.append(threading.Thread(target=nc.run, args=(stop, time.time), daemon=True))
        for thread in threads:
            thread.start()
        try:
            yield MachineNode(drive, node, nc)
        finally:
            stop.set()
            for thread in threads:
                thread.join()


def scenario_program(machine: Machine, period_s: float) -> FloatArray:
    """The ``[scenario]`` trajectory as targets one per bus cycle (from rest)."""
    ref = build_reference(machine.scenario)
    t = np.arange(0.0, ref.duration_s, period_s)
    return np.interp(t, ref.time_s, ref.position_m).astype(np.float64)


def read_program(path: Path, period_s: float) -> FloatArray:
    """A part program CSV (``time_s`` and ``position_m`` or ``reference_position_m``, as
    ``gms-comp profile`` writes) resampled to one target per bus cycle, from rest.

    Raises
    ------
    InputError
        One line: a column missing, time not increasing, a speed no linear axis has.
    """
    columns, _ = read_csv(path)
    position = columns.get("position_m", columns.get("reference_position_m"))
    if "time_s" not in columns or position is None:
        raise InputError(
            str(path), "", "a part program needs the columns time_s and position_m "
            f"(or reference_position_m); found {', '.join(columns) or 'none'}"
        )  # fmt: skip
    t = columns["time_s"]
    if t.size < 2 or np.any(np.diff(t) <= 0) or not np.all(np.isfinite(position)):
        raise InputError(str(path), "time_s", "must increase from row to row, positions finite")
    if t[-1] - t[0] > MAX_PROGRAM_S:
        raise InputError(str(path), "time_s", f"the program lasts more than {MAX_PROGRAM_S:g} s")
    speed = float(np.max(np.abs(np.diff(position) / np.diff(t))))
    if speed > MAX_PROGRAM_SPEED_M_S:
        raise InputError(
            str(path), "position_m", f"{speed:.3g} m/s between two rows: no linear axis moves "
            f"that fast (positions in mm? pass them in m)"
        )  # fmt: skip
    grid = np.arange(t[0], t[-1], period_s)
    return np.interp(grid, t, position).astype(np.float64)
