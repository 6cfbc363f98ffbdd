"""The emulated CiA 402 drive: a canopen LocalNode (SDO, EMCY) around the cia402 receiver,
hosting an axis in cyclic synchronous position when it has one (the simulated machine)."""

from __future__ import annotations

import can
import canopen

from firmware_bridge.profiles.cia402.codec import (
    EMCY_SYNC_LOST,
    FORCE_CONSTANT_MN_PER_A,
    MOTION_TPDO,
    NC_RPDO,
    POSITION_UNIT_PM,
    Cia402Codec,
    configure_drive,
    load_drive_od,
    read_object,
    write_object,
)
from firmware_bridge.profiles.cia402.in_drive import (
    TABLE_CRC,
    TABLE_LOADED,
    TABLE_OBJECT,
    InDriveObserver,
    accept_table,
)
from firmware_bridge.profiles.cia402.motion import PICOMETRE, AxisSample, DriveAxis
from firmware_bridge.profiles.cia402.receiver import Cia402Receiver
from firmware_bridge.profiles.cia402.statemachine import PowerState, PowerStateMachine
from firmware_bridge.settings import CanConfig
from firmware_bridge.supervisor import RejectCounts

EMCY_FOLLOWING_ERROR = 0x8611
SYNC_LOSS_S = 0.5
"""An axis in operation faults when SYNC has been gone this long (the NC stopped); a SYNC
late by a few cycles raises EMCY 0x8100 but keeps the axis enabled, holding. Generous for
a drive, because the NC here is a Python thread on a shared machine: at a load of 9 on 2
cores its SYNCs were 20-100 ms late now and then."""
MAX_MOVES_PER_TICK = 16
"""At most this many axis cycles run at once (a burst of SYNCs: the NC is broken)."""
_INT16, _INT32 = 2**15 - 1, 2**31 - 1


class Cia402Drive:
    """The drive side of cia402 on ``bus`` (implements ``DriveSide``).

    Parameters
    ----------
    cfg
        The ``[can]`` section; its supervision times are written into the
        object dictionary as an NC would by SDO at start-up.
    bus
        The drive's bus handle.
    axis
        The motion it hosts (the simulated machine's :class:`~sim.machine.CspAxis`), or
        None: a drive that moves nothing and takes the feedforward whenever it is
        operational (the emulator behind ``gms-comp stream``).

    At each SYNC it judges the feedforward RPDOs of the cycle (and, with an axis, takes
    the NC's controlword and target from RPDO1), and at every ``status_every_cycles``-th
    SYNC (the TPDOs' transmission type) it sends TPDO1 with its statusword, the last tick
    it ran and the session it holds (what the compensator dates its frames by) and the
    current, and with an axis TPDO2 with position and velocity, all sampled then.
    With an axis it runs the CiA 402 state machine: it follows the target and applies the
    feedforward only in "operation enabled", and faults when SYNC has been gone for
    :data:`SYNC_LOSS_S` or on a following error beyond the axis's limit (EMCY 0x8100,
    0x8611).

    Its control cycle is the SYNC, as a drive's PLL locks it to the NC's: the axis moves
    one bus cycle per SYNC (at the drive tick after it, with the feedforward applied
    then, or at the next SYNC if that comes first), so a SYNC early or late, or two
    within one of the drive's ticks, moves it exactly as on time, and the simulated
    machine's time is the NC's cycle count, whatever the host's scheduling (a Python NC
    on a loaded machine is late by milliseconds now and then). Without SYNC the axis
    holds where it is.
    """

    def __init__(self, cfg: CanConfig, bus: can.BusABC, axis: DriveAxis | None = None) -> None:
        od = load_drive_od(cfg.drive_node_id)
        self.node = canopen.LocalNode(cfg.drive_node_id, od)
        network = canopen.Network(bus)  # no notifier: the emulator dispatches itself
        network.add_node(self.node)
        configure_drive(self.node, cfg)
        self.codec = Cia402Codec(cfg, od)
        limit = min(self.codec.limit_raw, self.codec.to_raw(cfg.max_current_A))
        self.receiver = Cia402Receiver(self.node, self.codec, cfg, limit)
        self.status_every = cfg.status_every_cycles
        self._syncs = 0
        self.axis = axis
        self.power = PowerStateMachine()
        self.unit_m = read_object(self.node, POSITION_UNIT_PM) * PICOMETRE
        self.in_drive: InDriveObserver | None = None  # the observer of a downloaded table
        if axis is not None:
            write_object(self.node, FORCE_CONSTANT_MN_PER_A, None,
                         round(axis.force_constant_N_per_A * 1e3))  # fmt: skip
            self.node.add_write_callback(self._on_write)
        self.target_m = 0.0
        self.sync_loss_s = SYNC_LOSS_S
        self._nc: bytes | None = None  # the NC's RPDO1 since the last SYNC
        self._moves: list[float] = []  # the targets of the SYNCs since the last tick
        self._last_out = 0  # the 0x60B2 value the last tick applied
        self.sample: AxisSample | None = None

    @property
    def cycle_sync_cob_id(self) -> int | None:
        """With an axis, the drive's cycle is the SYNC (the emulator runs it at each one)."""
        return self.codec.sync_cob_id if self.axis is not None else None

    @property
    def counts(self) -> RejectCounts:
        """Received RPDOs by verdict."""
        return self.receiver.counts

    def handle(self, msg: can.Message, now_s: float) -> None:
        """Take one frame (RPDOs, SYNC, heartbeat, SDO, NMT); at a SYNC, the NC's command."""
        if msg.arbitration_id == self.codec.nc_cob_id and len(msg.data) == NC_RPDO.size:
            self._nc = bytes(msg.data)
            return
        if self.receiver.on_message(msg, now_s):
            if self._nc is not None and self.axis is not None:
                controlword, target = NC_RPDO.packing.unpack(self._nc)
                self.power.command(controlword)
                self.target_m = target * self.unit_m
            self._nc = None
            if self.axis is not None:
                # the cycles of earlier SYNCs not run yet (two SYNCs within one tick) run
                # first: what the TPDOs sample has followed every target before this one
                self._run_moves(self._last_out)
                self._moves.append(self.target_m)
            if self._syncs % self.status_every == 0:  # sampled at SYNC, as type-1 TPDOs are
                self._send_tpdos(msg.data[0] if len(msg.data) == 1 else 0)
            self._syncs += 1

    def set_real_time(self, real_time: bool) -> None:
        """Nothing to set: the drive's tick dates every frame, stepped or in real time."""

    def tick(self, now_s: float, cycle: int) -> tuple[int, bytes | None]:
        """One drive cycle; the applied 0x60B2 value and the RPDO applied fresh in it.
        The axis moves one bus cycle."""
        out = self.receiver.tick(now_s)
        if self.axis is not None:
            last_sync = self.receiver.last_sync_s
            if (
                self.power.enabled
                and last_sync is not None
                and now_s - last_sync > self.sync_loss_s
            ):
                self.power.fault(EMCY_SYNC_LOST)
            if last_sync is None:  # before the first SYNC it stands on the drive's ticks
                self._moves = [self.target_m]
            self._run_moves(out)
            self._last_out = out
        return out, self.receiver.applied_data

    def _run_moves(self, offset_raw: int) -> None:
        for target in self._moves[:MAX_MOVES_PER_TICK]:
            self._move(offset_raw, target)
        self._moves = []

    def _on_write(self, index: int, subindex: int, od: object, data: bytes) -> None:
        """An SDO download: a table for the observer in the drive (or an abort)."""
        if index != TABLE_OBJECT:
            return
        assert self.axis is not None
        crc = read_object(self.node, TABLE_CRC)
        table = accept_table(bytes(data), crc, f"drive {self.node.id} 0x{TABLE_OBJECT:04X}")
        self.in_drive = InDriveObserver(
            table, self.axis.force_constant_N_per_A, self.axis.servo_period_s
        )
        self.node.data_store.setdefault(TABLE_LOADED, {})[0] = table.n_elements.to_bytes(
            2, "little"
        )

    def _move(self, offset_raw: int, target_m: float) -> None:
        assert self.axis is not None
        enabled = self.power.enabled
        in_drive = None
        if self.receiver.in_drive and self.in_drive is not None:
            self.in_drive.set_level(offset_raw)  # the value is the level: no current of its own
            in_drive, offset_raw = self.in_drive, 0
        offset_A = self.codec.from_raw(offset_raw) if enabled else 0.0
        self.sample = self.axis.cycle(target_m, offset_A, enabled, in_drive)
        if enabled and abs(self.sample.following_error_m) > self.axis.max_following_error_m:
            self.power.fault(EMCY_FOLLOWING_ERROR)
            self.receiver.raise_fault(EMCY_FOLLOWING_ERROR)

    @property
    def statusword(self) -> int:
        """0x6041: the state machine's with an axis; without, operation enabled unless the
        feedforward link faulted or the node left operation."""
        if self.axis is not None:
            return self.power.statusword
        enabled = self.receiver.state in ("operation_enabled", "waiting")
        state = PowerState.OPERATION_ENABLED if enabled else PowerState.SWITCH_ON_DISABLED
        return state.value | 0x0200

    def _send_tpdos(self, sync_counter: int) -> None:
        receiver = self.receiver
        sample = self.sample
        current_raw = (
            receiver.supervisor.output_raw
            if sample is None
            else self.codec.to_raw(sample.current_A)
        )
        status = self.codec.status_frame(
            self.statusword,
            receiver.last_cycle,
            receiver.clock.session,
            max(-_INT16, min(_INT16, current_raw)),
            sync_counter,
        )
        network = self.node.network
        network.send_message(status.arbitration_id, bytes(status.data))
        if sample is not None:
            position = round(sample.position_m / self.unit_m)
            velocity = round(sample.velocity_m_s / self.unit_m)
            network.send_message(
                self.codec.motion_cob_id,
                MOTION_TPDO.packing.pack(_clip32(position), _clip32(velocity)),
            )

    def from_raw(self, raw: int) -> float:
        """Per mille of the rated current -> A."""
        return self.codec.from_raw(raw)

    def state(self) -> str:
        """The receiver's state (operation_enabled, waiting, or the 0x6007 reaction); with
        an axis, the CiA 402 state."""
        if self.axis is not None:
            return self.power.state.name.lower()
        return self.receiver.state

    def emcy(self) -> list[str]:
        """EMCY codes sent, as ``0xNNNN``."""
        return [f"0x{code:04X}" for code in self.receiver.emcy_sent]


def _clip32(value: int) -> int:
    return max(-_INT32, min(_INT32, value))
