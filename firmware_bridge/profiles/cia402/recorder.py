"""Recording a CiA 402 axis per SYNC: the NC's target and the drive's TPDOs, one row each.

Each SYNC opens a row; the frames that follow it until the next SYNC fill it: the
drive's TPDO1 (statusword, its cycle, current actual) and TPDO2 (position and velocity
actual), sent at the drive's tick after the SYNC; the target is the NC's RPDO1 sent
before that SYNC. A row whose TPDO did not come in time keeps NaN where it is missing and
is counted, never interpolated: a TPDO1 older (by the drive cycle it carries) than one
already taken is late and dropped with the TPDO2 that follows it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import can
import numpy as np

from firmware_bridge.freshness import stamp_age
from firmware_bridge.profiles.cia402.codec import MOTION_TPDO, NC_RPDO, Cia402Codec
from gms_comp.arrays import FloatArray

COLUMNS = ("reference_position_m", "position_m", "velocity_m_s", "current_A")
MAX_ROWS = 4_000_000  # a bound on memory: over an hour at 1 kHz


@dataclass
class Recording:
    """Rows per SYNC, in SI units (NaN where a frame was lost or late), and the counts."""

    unit_m: float
    rated_current_A: float
    rows: list[tuple[float, float, float, float]] = field(default_factory=list)
    slots: list[int] = field(default_factory=list)  # each row's SYNC slot (time / cycle)
    lost: dict[str, int] = field(default_factory=lambda: {"status": 0, "motion": 0, "target": 0})
    late: int = 0

    def column(self, name: str) -> FloatArray:
        """One column of :data:`COLUMNS` on the grid of SYNC slots from the first row's to
        the last's: NaN at a slot without a SYNC (the loop that sent them was late)."""
        i = COLUMNS.index(name)
        out = np.full(self.span, np.nan)
        if self.rows:
            first = self.slots[0]
            out[[s - first for s in self.slots]] = [row[i] for row in self.rows]
        return out

    @property
    def span(self) -> int:
        """Slots from the first row's to the last's."""
        return self.slots[-1] - self.slots[0] + 1 if self.slots else 0


class Recorder:
    """Assembles :class:`Recording` rows from the frames on the bus.

    Call :meth:`frame` for every frame received and :meth:`sync` at every SYNC (sent or
    seen) with the target the NC sent before it, if known.
    """

    def __init__(self, codec: Cia402Codec, unit_m: float, rated_current_A: float) -> None:
        self.codec = codec
        self.recording = Recording(unit_m, rated_current_A)
        self._open = False
        self._target = math.nan
        self._status: tuple[int, float] | None = None  # (drive cycle, current) of the row
        self._motion: tuple[float, float] | None = None
        self._last_cycle: int | None = None
        self._drop_next_motion = False
        self._pending_target = math.nan  # the NC's RPDO1 seen since the last SYNC
        self._slot = 0

    def frame(self, msg: can.Message) -> None:
        """One frame from the bus: the NC's target, or a TPDO for the open row."""
        data, cob_id = bytes(msg.data), msg.arbitration_id
        if cob_id == self.codec.nc_cob_id and len(data) == NC_RPDO.size:
            self._pending_target = NC_RPDO.packing.unpack(data)[1] * self.recording.unit_m
        elif cob_id == self.codec.status_cob_id and self._open:
            report = self.codec.unpack_status(data)
            if report is None:
                return
            last = self._last_cycle
            if last is not None and stamp_age(report.cycle, last) <= 0:
                self.recording.late += 1  # an older tick's: it missed its row
                self._drop_next_motion = True
                return
            if self._status is not None:
                self.recording.late += 1  # the row's own came after a late one
            current = report.current_raw * self.recording.rated_current_A / 1000
            self._status, self._last_cycle = (report.cycle, current), report.cycle
            self._drop_next_motion = False
        elif cob_id == self.codec.motion_cob_id and self._open and len(data) == MOTION_TPDO.size:
            if self._drop_next_motion:
                self._drop_next_motion = False
                return
            position, velocity = MOTION_TPDO.packing.unpack(data)
            unit = self.recording.unit_m
            self._motion = (position * unit, velocity * unit)

    def sync(self, slot: int, target_m: float | None = None) -> None:
        """A SYNC of time slot ``slot``: close the open row, open the next with ``target_m``
        (default: the NC's RPDO1 seen since the last SYNC)."""
        rec = self.recording
        if self._open:
            if len(rec.rows) >= MAX_ROWS:
                raise OverflowError(f"a recording holds at most {MAX_ROWS} rows")
            status, motion = self._status, self._motion
            rec.lost["status"] += status is None
            rec.lost["motion"] += motion is None
            rec.lost["target"] += math.isnan(self._target)
            rec.slots.append(self._slot)
            rec.rows.append(
                (
                    self._target,
                    math.nan if motion is None else motion[0],
                    math.nan if motion is None else motion[1],
                    math.nan if status is None else status[1],
                )
            )
        self._open, self._slot = True, slot
        self._target = self._pending_target if target_m is None else target_m
        self._pending_target = math.nan
        self._status = self._motion = None
