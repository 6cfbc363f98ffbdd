"""A simulated machine axis as a drive hosts it: cyclic synchronous position, one bus cycle
at a time, with a friction the compensator is not told about.

:class:`CspAxis` is the motion inside ``gms-comp machine``: every bus cycle the drive
hands it the NC's target position and the compensator's torque offset, and it advances
the plant (:class:`~sim.plant.LinearMotorAxis`, the full ball model as friction) under the
drive's own position/velocity loop (:class:`~sim.controller.CascadeController`) for the
servo cycles of that bus cycle, the target interpolated linearly between two bus
cycles. The ``[machine]`` section says what differs from the nominal ``[plant]``: a
hidden catalogue effect on top of the ball model (applied per servo cycle as a force held
over it, as the plant's friction), the true force constant, the encoder, the noise on
the measured current.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gms_comp.config import in_range, parse_section, positive, read_toml
from gms_comp.errors import ConfigError
from gms_comp.runtime import effects as fx
from gms_comp.runtime.effects.stream import ExtensionStream
from gms_comp.validation import MAX_SEED
from sim.controller import CascadeController, design
from sim.plant import LinearMotorAxis, ScaledFriction
from sim.scenarios import Scenario, ball_set_friction, load_scenario


@dataclass(frozen=True)
class MachineConfig:
    """The ``[machine]`` section: the simulated machine behind ``gms-comp machine``.

    ``effect`` is a catalogue effect (``gms-comp diagnose`` names the same) or "none";
    its parameters are further keys of the section, under the names the diagnosis
    prints (``amplitude_N``, ``wavelength_m``, ``phase_rad`` for ``position_ripple``,
    ...). ``force_constant_N_per_A`` and ``encoder_resolution_m`` are the machine's true
    values (the compensator works with ``[plant]``'s).
    """

    effect: str = "none"
    current_noise_A: float = field(default=0.005, metadata=in_range(0.0, 10.0))
    encoder_resolution_m: float = field(default=1e-9, metadata=in_range(0.0, 1e-3))
    force_constant_N_per_A: float = field(default=60.0, metadata=in_range(1e-2, 1e4))
    max_following_error_m: float = field(default=2e-3, metadata=positive(1.0))
    noise_seed: int = field(default=0, metadata=in_range(0, MAX_SEED))

    def problems(self) -> list[tuple[str, str]]:
        """`effect` is a catalogue name or "none"."""
        if self.effect != "none" and self.effect not in fx.CATALOGUE:
            known = ", ".join(["none", *fx.CATALOGUE])
            return [("effect", f"must be one of {known}, got {self.effect!r}")]
        return []


@dataclass(frozen=True)
class Machine:
    """A simulated machine: the nominal scenario, what the machine hides, its effect."""

    scenario: Scenario
    config: MachineConfig
    effect: fx.Effect | None


def load_machine(path: str | Path | None = None) -> Machine:
    """The scenario of ``path`` and its ``[machine]`` section (effect parameters included).

    Raises
    ------
    ConfigError
        One line naming the file and the key: an unknown effect, its parameters missing
        or wrong, a value out of its range.
    """
    s = load_scenario(path)
    doc = read_toml(s.path)
    section: Mapping[str, Any] = doc.get("machine", {})
    cfg = parse_section(machine_section(doc), s.path, "machine", MachineConfig)
    own = {f.name for f in dataclasses.fields(MachineConfig)}
    extra = {k: v for k, v in section.items() if k not in own}
    effect = None
    if cfg.effect != "none":
        try:
            effect = fx.effect_from_dict({"effect": cfg.effect, "parameters": extra})
        except fx.ExtensionError as err:
            raise ConfigError(s.path, "machine", str(err).replace("table extension ", "")) from None
    elif extra:
        raise ConfigError(s.path, f"machine.{sorted(extra)[0]}", "unknown key (effect is none)")
    return Machine(s, cfg, effect)


def machine_section(doc: Mapping[str, Any]) -> dict[str, Any]:
    """``doc`` with ``[machine]`` cut to :class:`MachineConfig`'s own keys (the rest are the
    effect's parameters, which :func:`load_machine` checks)."""
    section = doc.get("machine")
    if not isinstance(section, Mapping):
        return dict(doc)
    own = {f.name for f in dataclasses.fields(MachineConfig)}
    return {**doc, "machine": {k: v for k, v in section.items() if k in own}}


@dataclass(frozen=True)
class AxisSample:
    """What the drive reads off the axis at the end of a bus cycle (SI units)."""

    position_m: float  # the encoder's reading
    velocity_m_s: float  # the drive's velocity estimate
    current_A: float  # the measured motor current, with its noise
    following_error_m: float  # target less the encoder's reading


class CspAxis:
    """The machine's axis under its drive's loop, one bus cycle per :meth:`cycle`.

    Parameters
    ----------
    machine
        The machine (:func:`load_machine`).
    cycle_period_s
        The bus cycle: SYNC to SYNC.
    """

    def __init__(self, machine: Machine, cycle_period_s: float) -> None:
        s, m = machine.scenario, machine.config
        plant = dataclasses.replace(
            s.plant,
            force_constant_N_per_A=m.force_constant_N_per_A,
            encoder_resolution_m=m.encoder_resolution_m,
        )
        servo_s = s.controller.servo_period_s
        self.substeps = max(1, round(cycle_period_s / servo_s))
        self.cycle_period_s = cycle_period_s
        self.servo_period_s = cycle_period_s / self.substeps
        self.force_constant_N_per_A = m.force_constant_N_per_A
        truth = ScaledFriction(ball_set_friction(s.ball), s.plant.ball_set_count)
        self.axis = LinearMotorAxis(plant, truth, cycle_period_s / self.substeps)
        # the drive's loop is tuned on the nominal plant, as a drive is commissioned
        self.controller = CascadeController(
            design(s.plant, dataclasses.replace(s.controller, servo_rate_Hz=1 / servo_s)),
            s.plant.current_limit_A,
            s.controller.acceleration_lead_cycles,
        )
        self.effect = machine.effect
        self.current_noise_A = m.current_noise_A
        self.max_following_error_m = m.max_following_error_m
        self._rng = np.random.default_rng(m.noise_seed)
        self._stream: ExtensionStream | None = None
        if machine.effect is not None:
            # every effect gets the guide's GMS (0.2-0.4 s): one on the elements needs it
            self._stream = ExtensionStream([machine.effect], self.servo_period_s, gms=_gms_of(s))
        self.reset()

    def reset(self) -> None:
        """At rest at 0 m, the loop holding it, the effect's history forgotten."""
        self.axis.reset()
        self.controller.reset(0.0)
        self.time_s = 0.0
        self._last_v = 0.0
        self._hidden_steps = 0  # servo cycles the hidden effect has seen
        self.targets = [0.0, 0.0]  # the last two targets, for the interpolation
        self.position_m = self.axis.measure()
        if self._stream is not None:
            self._stream.reset()

    def cycle(
        self,
        target_position_m: float,
        torque_offset_A: float,
        enabled: bool,
        in_drive: Callable[[float, float], float] | None = None,
    ) -> AxisSample:
        """One bus cycle: follow ``target_position_m`` (held if the drive is not enabled),
        the feedforward ``torque_offset_A`` added to the loop's current command, and
        ``in_drive(position, velocity)`` (the drive's own observer) each servo cycle, on
        the position command and its speed: on the encoder, a reversal transient's
        extension turned with the axis's ringing after each reversal (559 nm peak with the
        true parameters against 447 nm without feedforward; 27 nm on the command)."""
        previous, before = self.targets[-1], self.targets[-2]
        if not enabled:
            target_position_m = self.position_m
            self.controller.reset(self.position_m)
        step = (target_position_m - previous) / self.substeps
        accel = (target_position_m - 2 * previous + before) / self.cycle_period_s**2
        # the loop is one servo cycle ahead of its reference (its velocity feedforward
        # moves the axis through the servo cycle): at the end of the bus cycle it stands
        # at the target
        for i in range(self.substeps):
            if enabled:
                offset = torque_offset_A
                if in_drive is not None:  # on the position command, as it moves
                    offset += in_drive(previous + i * step, step / self.servo_period_s)
                command = self.controller.step(self.position_m, previous + i * step, accel, offset)
            else:
                command = 0.0
            self._hold_hidden_force(previous + i * step if enabled else self.axis.position_m)
            self.position_m = self.axis.step(command)
        self.targets = [previous, target_position_m]
        self.time_s += self.cycle_period_s
        current = self.axis.current_A + self.current_noise_A * float(self._rng.standard_normal())
        return AxisSample(
            self.position_m,
            self.controller.velocity_m_s if enabled else self.axis.velocity_m_s,
            current,
            target_position_m - self.position_m,
        )

    def _hold_hidden_force(self, path_m: float) -> None:
        """The hidden effect's force at the start of the servo cycle, held over it (at
        the bus cycle, a force that turns with the motion, held 1 ms, shook the loop)."""
        if self._stream is None:
            return
        x, v = path_m, self.axis.velocity_m_s
        base = self.axis.friction_force_N - self.axis.io[2]
        accel = 0.0 if self._hidden_steps == 0 else (v - self._last_v) / self.servo_period_s
        self._last_v = v
        extended = self._stream.step(self._hidden_steps * self.servo_period_s, x, v, accel, base)
        self._hidden_steps += 1
        self.axis.hold_extra_force(extended - base)


def _gms_of(s: Scenario) -> Any:
    """The GMS an effect on its elements acts on: the ball model's table, for the guide."""
    from gms_comp.gms import scaled
    from gms_comp.tables.reduction import reduce_to_gms

    table = reduce_to_gms(s.ball)
    return scaled(table.params, s.plant.ball_set_count, 1.0)
