"""Recording a CiA 402 axis per SYNC: the NC's target and the drive's TPDOs, one row each.

Each SYNC opens a row under its slot (its time) and its CiA 301 counter byte. The drive
samples its TPDOs at SYNC, before it moves on to the target that SYNC brought: the row's
target is therefore the one of the SYNC before (the NC's RPDO1 sent before it), which the
sampled state has followed for a cycle. The drive samples its TPDOs at SYNC and sends
them at once: TPDO1 (statusword, current actual) names the SYNC it answers by that
counter (object 0x2006), so it is filed under its own row however late it comes (counted
``late`` when it came after the next SYNC); TPDO2 (position and velocity actual) goes
with the TPDO1 just before it. A row after a SYNC that never came (the NC or the bus
stalled) has no target: the one it followed came with a SYNC not seen. A row is closed
when its counter comes round again or the recording ends; what never came stays NaN and
is counted ``lost``, never interpolated.
Without a counter in the SYNC (0), a TPDO goes to the row open when it arrives.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass, field

import can
import numpy as np

from firmware_bridge.profiles.base import SYNC_COUNTER_OVERFLOW
from firmware_bridge.profiles.cia402.codec import MOTION_TPDO, NC_RPDO, Cia402Codec
from gms_comp.arrays import FloatArray

COLUMNS = ("reference_position_m", "position_m", "velocity_m_s", "current_A")
MAX_ROWS = 4_000_000  # a bound on memory: over an hour at 1 kHz
OPEN_ROWS = SYNC_COUNTER_OVERFLOW // 2  # rows kept open for late TPDOs


@dataclass
class Recording:
    """Rows per SYNC, in SI units (NaN where a frame was lost), and the counts."""

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


@dataclass
class _Row:
    slot: int
    target_m: float
    current_A: float = math.nan
    position_m: float = math.nan
    velocity_m_s: float = math.nan


class Recorder:
    """Assembles :class:`Recording` rows from the frames on the bus.

    Call :meth:`frame` for every frame received and :meth:`sync` at every SYNC (sent or
    seen), then :meth:`finish`.
    """

    def __init__(self, codec: Cia402Codec, unit_m: float, rated_current_A: float) -> None:
        self.codec = codec
        self.recording = Recording(unit_m, rated_current_A)
        self._open: OrderedDict[int, _Row] = OrderedDict()  # by SYNC counter, oldest first
        self._newest: int | None = None  # the counter of the last SYNC
        self._for_motion: _Row | None = None  # the row of the TPDO1 just before
        self._pending_target = math.nan  # the NC's RPDO1 seen since the last SYNC
        self._followed = math.nan  # the target of the last SYNC: what the drive follows
        self._last_slot: int | None = None  # the slot of the last SYNC

    def frame(self, msg: can.Message) -> None:
        """One frame from the bus: the NC's target, or a TPDO for its row."""
        data, cob_id = bytes(msg.data), msg.arbitration_id
        unit = self.recording.unit_m
        if cob_id == self.codec.nc_cob_id and len(data) == NC_RPDO.size:
            self._pending_target = NC_RPDO.packing.unpack(data)[1] * unit
        elif cob_id == self.codec.status_cob_id:
            report = self.codec.unpack_status(data)
            key = (
                self._newest
                if report is None or report.sync_counter == 0
                else (report.sync_counter)
            )
            row = self._open.get(key) if key is not None else None
            self._for_motion = row
            if report is None or row is None:
                return
            if key != self._newest:
                self.recording.late += 1
            row.current_A = report.current_raw * self.recording.rated_current_A / 1000
        elif cob_id == self.codec.motion_cob_id and len(data) == MOTION_TPDO.size:
            row, self._for_motion = self._for_motion, None
            if row is not None:
                position, velocity = MOTION_TPDO.packing.unpack(data)
                row.position_m, row.velocity_m_s = position * unit, velocity * unit

    def sync(self, slot: int, counter: int, target_m: float | None = None) -> None:
        """A SYNC of time slot ``slot`` with counter byte ``counter`` (0: none), bringing
        ``target_m`` (default: the NC's RPDO1 seen since the last SYNC): a new row, whose
        target is the previous SYNC's if that was the slot just before (else NaN)."""
        key = counter if counter else -slot  # without a counter, rows close in order
        if key in self._open:
            self._close(self._open.pop(key))
        while len(self._open) >= OPEN_ROWS:
            self._close(self._open.popitem(last=False)[1])
        target = self._pending_target if target_m is None else target_m
        followed = self._followed if self._last_slot == slot - 1 else math.nan
        self._open[key] = _Row(slot, followed)
        self._newest, self._pending_target, self._followed = key, math.nan, target
        self._last_slot = slot

    def finish(self) -> Recording:
        """Close every open row; the recording, rows in slot order."""
        for row in self._open.values():
            self._close(row)
        self._open.clear()
        rec = self.recording
        order = np.argsort(rec.slots, kind="stable")
        rec.slots = [rec.slots[i] for i in order]
        rec.rows = [rec.rows[i] for i in order]
        return rec

    def _close(self, row: _Row) -> None:
        rec = self.recording
        if len(rec.rows) >= MAX_ROWS:
            raise OverflowError(f"a recording holds at most {MAX_ROWS} rows")
        rec.lost["status"] += math.isnan(row.current_A)
        rec.lost["motion"] += math.isnan(row.position_m)
        rec.lost["target"] += math.isnan(row.target_m)
        rec.slots.append(row.slot)
        rec.rows.append((row.target_m, row.position_m, row.velocity_m_s, row.current_A))
