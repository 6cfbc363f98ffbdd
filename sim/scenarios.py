"""A simulation scenario: configs, the friction truth, the strategies and their scores.

The default scenario (every section at its defaults, physics from the packaged
Table 1 config) is one axis of a circularity test on a linear-motor axis of a
precision machine: a 30 kg carriage on a guide whose friction is 40 copies of
the seed's four-ball set (160 balls at 50 N: four carriages with four ball rows
of ten loaded balls; about 11 N of sliding friction, a realistic level for
preloaded profile-rail guides without seals), a 10 mm radius circle at
1.2 m/min, one servo cycle of transport delay. The seed's stand alone (0.3 N)
would give following errors at the nanometre noise floor of the encoder.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from gms_comp.arrays import FloatArray
from gms_comp.config import default_config_path, in_range, parse_section, positive, read_toml
from gms_comp.errors import ConfigError, ScenarioError
from gms_comp.physics.config import BallConfig, load_ball_config
from gms_comp.physics.profiles import seed_fig7_profile
from gms_comp.physics.transient import BallSetFriction
from gms_comp.runtime.observer import (
    CompensatorConfig,
    ForceModel,
    FrictionObserver,
    check_table_fits,
)
from gms_comp.tables.reduction import reduce_to_gms
from gms_comp.tables.table import GmsTable, read_table
from sim.closed_loop import RunResult, run
from sim.controller import CascadeController, ControllerConfig, design
from sim.link import DirectLink, FeedforwardLink
from sim.plant import LinearMotorAxis, PlantConfig, ScaledFriction, compiled_truth
from sim.position_loop import PositionLoop, RigidAxisModel, simulate_loop
from sim.strategies import REGISTRY, STRATEGIES, Calibration, StrategyInputs, calibrate
from sim.trajectories import Reference, circle, reversals, sine, step_stop, stops

#: Duration of a simulated scenario (its motion, smoothing windows and final dwell), s.
MAX_DURATION_S = 600.0
#: Servo cycles of a simulated scenario (duration x servo rate), checked before any array
#: of the run is made: every cycle costs a few dozen bytes per strategy and axis.
MAX_SCENARIO_CYCLES = 4_000_000


@dataclass(frozen=True)
class ScenarioConfig:
    """The ``[scenario]`` section: trajectory, delays and scoring windows."""

    trajectory: Literal["circle", "sine", "step_stop"] = "circle"
    circle_axis: Literal["x", "y", "xy"] = "x"
    radius_m: float = field(default=0.01, metadata=in_range(1e-6, 1.0))
    feed_m_s: float = field(default=0.02, metadata=in_range(1e-6, 10.0))
    revolutions: float = field(default=1.0, metadata=positive(1e3))
    amplitude_m: float = field(default=1e-3, metadata=positive(1.0))
    frequency_Hz: float = field(default=2.0, metadata=in_range(1e-3, 1e3))
    periods: float = field(default=2.0, metadata=positive(1e5))
    acceleration_window_s: float = field(default=0.01, metadata=positive(10.0))
    jerk_window_s: float = field(default=0.005, metadata=positive(10.0))
    dwell_s: float = field(default=0.2, metadata=positive(60.0))
    transport_delay_cycles: int = field(default=1, metadata=in_range(0, 1000))
    reversal_window_s: float = field(default=0.15, metadata=positive(10.0))
    min_stop_s: float = field(default=0.01, metadata=positive(10.0))
    calibration_travel_m: float = field(default=1e-3, metadata=positive(1.0))
    calibration_velocities_m_s: tuple[float, ...] = field(
        default=(0.01, 0.05), metadata=positive(10.0, max_items=8)
    )

    def problems(self) -> list[tuple[str, str]]:
        """`calibration_velocities_m_s` holds two distinct speeds."""
        v = self.calibration_velocities_m_s
        if len(v) != 2 or v[0] == v[1]:
            return [("calibration_velocities_m_s", f"must be two distinct speeds, got {list(v)}")]
        return []


@dataclass(frozen=True)
class Scenario:
    """Everything a run needs, read from one config file."""

    path: str
    ball: BallConfig
    plant: PlantConfig
    controller: ControllerConfig
    scenario: ScenarioConfig
    compensator: CompensatorConfig


def load_scenario(path: str | Path | None = None) -> Scenario:
    """Read the physics and simulation sections of ``path`` (default: Table 1) and check
    them together (:func:`check_scenario`), before any run is set up."""
    p = Path(path) if path is not None else default_config_path()
    doc = read_toml(p)
    s = Scenario(
        path=str(p),
        ball=load_ball_config(p),
        plant=parse_section(doc, p, "plant", PlantConfig),
        controller=parse_section(doc, p, "controller", ControllerConfig),
        scenario=parse_section(doc, p, "scenario", ScenarioConfig),
        compensator=parse_section(doc, p, "compensator", CompensatorConfig),
    )
    check_scenario(s)
    return s


def scenario_duration_s(c: ScenarioConfig) -> float:
    """How long the scenario's reference lasts: its motion, the smoothing windows and the
    final dwell (computed from the config, before the reference is made)."""
    motion_s = {
        "circle": c.revolutions * 2 * math.pi * c.radius_m / c.feed_m_s,
        "sine": c.periods / c.frequency_Hz,
        "step_stop": float(seed_fig7_profile(1e3)[0][-1]),
    }[c.trajectory]
    return motion_s + c.acceleration_window_s + c.jerk_window_s + c.dwell_s


def check_scenario(s: Scenario) -> None:
    """Refuse a scenario no run could make: one that lasts too long or has too many
    cycles (checked from the config, before anything is allocated), a trajectory the axis
    cannot follow, a compensator the drive-command loop does not take, a table file
    that is not a table. Every command that runs a scenario calls it through
    :func:`load_scenario`, and ``gms-comp config`` does, so they agree."""
    c = s.scenario
    duration_s = scenario_duration_s(c)
    cycles = duration_s * s.controller.servo_rate_Hz
    if duration_s > MAX_DURATION_S:
        raise ConfigError(
            s.path, "scenario", f"lasts {duration_s:.4g} s, more than {MAX_DURATION_S:.0f} s"
        )
    if cycles > MAX_SCENARIO_CYCLES:
        raise ConfigError(
            s.path,
            "scenario",
            f"{duration_s:.4g} s at {s.controller.servo_rate_Hz:g} Hz is {cycles:.3g} servo "
            f"cycles, more than {MAX_SCENARIO_CYCLES:,}",
        )
    comp = s.compensator
    if s.controller.structure == "position_velocity" and _drive_loop_problem(comp):
        raise ConfigError(s.path, "compensator", _drive_loop_problem(comp))
    if comp.table_path:
        table = Path(s.path).parent / comp.table_path
        if not table.is_file():
            raise ConfigError(s.path, "compensator.table_path", f"{str(table)!r} is not a file")
        read_table(table)
    for axis in axis_scenarios(s):
        build_reference(axis)


def _drive_loop_problem(comp: CompensatorConfig) -> str:
    """Why the drive-command loop cannot take this compensator ("" when it can)."""
    if comp.feed != "reference" or comp.adaptation_rate_per_s:
        return (
            "the position_velocity loop takes a reference-fed compensator without "
            "adaptation (compensator.feed, compensator.adaptation_rate_per_s)"
        )
    return ""


def load_plant(path: str | Path | None = None) -> PlantConfig:
    """The ``[plant]`` section of ``path`` (default: Table 1): the axis a table is made for
    (its ``ball_set_count`` scales the one ball set of the physics to the whole axis)."""
    p = Path(path) if path is not None else default_config_path()
    return parse_section(read_toml(p), p, "plant", PlantConfig)


def build_reference(s: Scenario) -> Reference:
    """The scenario's trajectory at the servo rate; refuse one the axis cannot follow.

    A two-axis circle (``circle_axis = "xy"``) gives its x axis here; :func:`axis_scenarios`
    splits it into one scenario per axis.
    """
    c = s.scenario
    smooth = (s.controller.servo_period_s, c.acceleration_window_s, c.jerk_window_s, c.dwell_s)
    if c.trajectory == "circle":
        ref = circle(c.radius_m, c.feed_m_s, c.revolutions, *smooth)[c.circle_axis == "y"]
    elif c.trajectory == "sine":
        ref = sine(c.amplitude_m, c.frequency_Hz, c.periods, *smooth)
    else:
        ref = step_stop(*smooth)
    needed_A = np.max(np.abs(ref.acceleration_m_s2)) * s.plant.moving_mass_kg
    needed_A /= s.plant.force_constant_N_per_A
    if needed_A > 0.8 * s.plant.current_limit_A:
        raise ScenarioError(
            f"{s.path}: the trajectory needs {needed_A:.3g} A to accelerate the mass, more than "
            f"80 % of plant.current_limit_A = {s.plant.current_limit_A:g} A"
        )
    return ref


def ball_set_friction(ball: BallConfig) -> ForceModel:
    """The friction truth of one ball set: the physics layer's transient ball model."""
    return BallSetFriction(ball)


def reduced_table(s: Scenario) -> GmsTable:
    """The GMS table of the whole axis: the configured file (refused if its force needs
    more than the feedforward's current limit), else reduced from the ball model
    ([table]) for the plant's ``ball_set_count`` ball sets."""
    comp = s.compensator
    if not comp.table_path:
        return reduce_to_gms(s.ball, ball_sets=s.plant.ball_set_count)
    path = Path(s.path).parent / comp.table_path
    table = read_table(path)
    check_table_fits(
        table, str(path), s.plant.force_constant_N_per_A, comp.friction_level_scale,
        comp.current_limit_A,
    )  # fmt: skip
    return table


@dataclass(frozen=True)
class Physics:
    """Where the truth and the table come from (replaceable in tests)."""

    truth: Callable[[BallConfig], ForceModel] = ball_set_friction
    table: Callable[[Scenario], GmsTable] = reduced_table


def build_observer(s: Scenario, name: str, physics: Physics) -> FrictionObserver | None:
    """The compensator of strategy ``name`` (None for ``none``)."""
    comp = s.compensator

    def calibration() -> Calibration:
        c = s.scenario
        v1, v2 = c.calibration_velocities_m_s
        truth = ScaledFriction(physics.truth(s.ball), s.plant.ball_set_count)
        return calibrate(truth, c.calibration_travel_m, (v1, v2))

    inputs = StrategyInputs(calibration, lambda: physics.table(s), comp.coulomb_velocity_band_m_s)
    source: GmsTable | ForceModel | None = REGISTRY[name].source(inputs)
    if source is None:
        return None
    return FrictionObserver(
        source, s.plant.force_constant_N_per_A, s.controller.servo_period_s,
        comp.friction_level_scale, comp,
    )  # fmt: skip


@dataclass(frozen=True)
class Loop:
    """The closed loop of a scenario: reference, axis with its truth, controller."""

    scenario: Scenario
    reference: Reference
    axis: LinearMotorAxis
    controller: CascadeController

    @classmethod
    def build(cls, s: Scenario, physics: Physics) -> Loop:
        """Reference, truth (scaled to the guide) and controller of ``s``."""
        truth = ScaledFriction(physics.truth(s.ball), s.plant.ball_set_count)
        controller = CascadeController(
            design(s.plant, s.controller),
            s.plant.current_limit_A,
            s.controller.acceleration_lead_cycles,
        )
        axis = LinearMotorAxis(s.plant, truth, s.controller.servo_period_s)
        return cls(s, build_reference(s), axis, controller)

    def run(self, observer: FrictionObserver | None, link: FeedforwardLink) -> RunResult:
        """One run from rest with ``observer`` (None: no compensation) behind ``link``."""
        comp = self.scenario.compensator
        if self.scenario.controller.structure == "position_velocity":
            return self._run_drive_loop(observer, link)
        return run(
            self.reference,
            self.axis,
            self.controller,
            link,
            observer,
            comp.feed,
            comp.look_ahead_cycles,
        )

    def _run_drive_loop(
        self, observer: FrictionObserver | None, link: FeedforwardLink
    ) -> RunResult:
        """The drive-command loop of :mod:`sim.position_loop` (the EMPS benchmark's, the
        replay's kernel) on a rigid axis of the plant's mass with this scenario's truth.

        The compensator is fed with the reference, so its output is computed first; its
        current becomes drive command units through ``k_f / drive gain``. The run's
        ``current_command_A`` holds the drive command.
        """
        s = self.scenario
        comp = s.compensator
        if observer is not None and _drive_loop_problem(comp):
            raise ScenarioError(f"{s.path}: {_drive_loop_problem(comp)}")
        ref = self.reference
        n = ref.cycles
        feedforward_A = np.zeros(n)
        if observer is not None:
            observer.reset()
        for k in range(n):
            wanted = 0.0
            if observer is not None:
                j = min(k + comp.look_ahead_cycles, n - 1)
                wanted = observer.step(float(ref.position_m[j]), float(ref.velocity_m_s[j]))
            feedforward_A[k] = link.transfer(k, wanted)
        friction = self.axis.friction
        friction.reset()
        loop = PositionLoop.from_config(s.controller, substeps=s.plant.substeps)
        to_command = s.plant.force_constant_N_per_A / loop.drive_gain_N
        r = simulate_loop(
            loop, RigidAxisModel(s.plant.moving_mass_kg), ref.position_m,
            feedforward_A * to_command, truth=compiled_truth(friction),
        )  # fmt: skip
        return RunResult(ref, r.position_m, feedforward_A, r.command, r.friction_N)


def run_strategies(
    s: Scenario,
    strategies: Iterable[str] = STRATEGIES,
    physics: Physics | None = None,
    link: Callable[[int], FeedforwardLink] = DirectLink,
    progress: Callable[[str], None] | None = None,
) -> dict[str, RunResult]:
    """Run the scenario once per strategy; ``link(delay_cycles)`` makes each link;
    ``progress(name)`` is told before each run."""
    physics = physics or Physics()
    loop = Loop.build(s, physics)
    results = {}
    for name in strategies:
        if name not in STRATEGIES:
            raise ScenarioError(f"unknown strategy {name!r} (known: {', '.join(STRATEGIES)})")
        if progress is not None:
            progress(name)
        observer = build_observer(s, name, physics)
        results[name] = loop.run(observer, link(s.scenario.transport_delay_cycles))
    return results


def axis_scenarios(s: Scenario) -> tuple[Scenario, ...]:
    """One scenario per simulated axis: ``s`` itself, or for a two-axis circle
    (``circle_axis = "xy"``) its x and its y axis, identical but for the reference and
    the encoder noise.

    The axes are mechanically independent, so each runs on its own plant, controller,
    friction truth and compensator, and a contour is two single-axis runs.
    """
    c = s.scenario
    if c.trajectory != "circle" or c.circle_axis != "xy":
        return (s,)
    # Each axis has its own encoder: the y axis draws its own noise sequence.
    axes: tuple[tuple[int, Literal["x", "y"]], ...] = ((0, "x"), (1, "y"))
    return tuple(
        dataclasses.replace(
            s,
            scenario=dataclasses.replace(c, circle_axis=axis),
            plant=dataclasses.replace(s.plant, noise_seed=s.plant.noise_seed + offset),
        )
        for offset, axis in axes
    )


def radial_error(x: RunResult, y: RunResult, radius_m: float) -> FloatArray:
    """Actual minus commanded radius of a two-axis circle, per servo cycle.

    The circle of :func:`circle` is centred on ``(0, radius_m)``; both radii are taken
    about that centre at the same instant, so the smoothing filter's slightly smaller
    commanded path does not count as error.
    """
    actual = np.hypot(x.position_m, y.position_m - radius_m)
    commanded = np.hypot(x.reference.position_m, y.reference.position_m - radius_m)
    return actual - commanded


def circularity(x: RunResult, y: RunResult, c: ScenarioConfig) -> dict[str, float | None]:
    """Contour scores of a two-axis circle (m).

    ``peak_quadrant_error_m``: the largest radial deviation within ``reversal_window_s``
    after each quadrant change, where either axis reverses or starts from rest (a full
    circle from the bottom point has three reversals; its fourth quadrant change is the
    y axis breaking away at the start). ``rms_radial_error_m``: over the whole run.
    """
    radial = radial_error(x, y, c.radius_m)
    window = max(1, round(c.reversal_window_s / x.reference.period_s))
    turns = np.unique(np.concatenate([_quadrant_changes(r.reference) for r in (x, y)]))
    peaks = [float(np.abs(radial[r : r + window]).max()) for r in turns]
    return {
        "peak_quadrant_error_m": max(peaks, default=None),
        "rms_radial_error_m": float(np.sqrt(np.mean(radial**2))),
    }


def _quadrant_changes(reference: Reference) -> NDArray[np.intp]:
    """Cycles where one axis reverses or leaves a standstill."""
    moving = reference.velocity_m_s != 0.0
    starts = np.flatnonzero(moving & ~np.concatenate([[False], moving[:-1]]))
    return np.union1d(starts, reversals(reference))


def score(result: RunResult, c: ScenarioConfig) -> dict[str, float | None]:
    """Peak error after reversals and during stops, and the rms error (m).

    A peak is ``None`` when the trajectory has no reversal or no stop.
    """
    error = np.abs(result.error_m)
    window = max(1, round(c.reversal_window_s / result.reference.period_s))
    at_reversals = [float(error[r : r + window].max()) for r in reversals(result.reference)]
    at_stops = [float(error[a:b].max()) for a, b in stops(result.reference, c.min_stop_s)]
    return {
        "peak_reversal_error_m": max(at_reversals, default=None),
        "rms_error_m": float(np.sqrt(np.mean(result.error_m**2))),
        "peak_stop_error_m": max(at_stops, default=None),
    }
