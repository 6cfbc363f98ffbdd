"""One closed-loop run: reference -> compensator -> link -> controller -> axis.

Per servo cycle ``k``: the encoder is read, the compensator steps (on the
reference ``look_ahead`` cycles ahead, or on the measurement), its current goes
through the feedforward link, the controller adds it to its command, and the
axis advances one cycle. The following error is the reference minus the true
position at the same instant (the tool sees the true position).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any, Literal

import numba
import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.runtime.observer import (
    PARAMS,
    ForceModel,
    FrictionObserver,
    adapt_level,
    feedforward_current,
)
from sim.controller import MEASURED_VELOCITY, CascadeController, controller_step
from sim.link import DirectLink, FeedforwardLink, delayed_hold
from sim.plant import LinearMotorAxis, axis_cycle
from sim.strategies import CompiledModel, CoulombViscous, compiled_form
from sim.trajectories import Reference

Signals = tuple[Any, ...]
# Placeholder for a run without a compensator (never stepped).
_NO_MODEL = CoulombViscous(0.0, 0.0, 1.0).compiled()


@dataclass(frozen=True)
class RunResult:
    """Signals of one run, one sample per servo cycle."""

    reference: Reference
    position_m: FloatArray
    feedforward_A: FloatArray
    current_command_A: FloatArray
    friction_N: FloatArray

    @property
    def error_m(self) -> FloatArray:
        """Following error: reference minus true position."""
        return self.reference.position_m - self.position_m


def compiled_model(model: ForceModel) -> CompiledModel | None:
    """The compiled step of a feedforward model, None if it has none (a table with
    physical extensions, any other Python model)."""
    return compiled_form(model)


@numba.njit(cache=True)
def _observer_input(
    k: int, ref: Signals, look_ahead: int, feed_measured: bool, measured: float, ctrl: Signals
) -> tuple[float, float]:  # pragma: no cover
    """What the compensator sees in cycle ``k``: the reference ahead, or the measurement."""
    if feed_measured:
        return measured, ctrl[1][MEASURED_VELOCITY]
    j = min(k + look_ahead, ref[0].size - 1)
    return ref[0][j], ref[1][j]


@numba.njit(cache=True)
def _feedforward(
    k: int,
    force_N: float,
    obs: Signals,
    ref: Signals,
    axis: Signals,
    inertial_gain: float,
    ctrl: Signals,
) -> float:  # pragma: no cover
    """The observer's current for ``force_N``, then its level adaptation (the drive's
    current, the reference's inertial current, the measured velocity)."""
    state, params = obs
    wanted = feedforward_current(state, params, force_N)
    x = axis[0]
    adapt_level(state, params, x[2], inertial_gain * ref[2][k], ctrl[1][MEASURED_VELOCITY])
    return wanted


@numba.njit(cache=True)
def _actuate(
    k: int,
    ff_A: float,
    measured: float,
    ref: Signals,
    lead: int,
    ctrl: Signals,
    axis: Signals,
    out: Signals,
) -> float:  # pragma: no cover
    """Controller and axis for cycle ``k`` with the applied feedforward; the new reading."""
    position, feedforward, command, friction = out
    x, ad, bd, params, io, noise, truth = axis
    n = ref[0].size
    position[k] = x[0]
    feedforward[k] = ff_A
    command[k] = controller_step(
        ctrl[0], ctrl[1], measured, ref[0][k], ref[2][min(k + lead, n - 1)], ff_A
    )
    reading = axis_cycle(x, ad, bd, params, io, noise, truth, command[k])
    friction[k] = io[1]
    return reading


@numba.njit(cache=True)
def _run_compiled(
    ref: Signals,
    step: Signals,
    model: Signals,
    has_observer: bool,
    obs: Signals,
    look_ahead: int,
    feed_measured: bool,
    inertial_gain: float,
    link: Signals,
    ctrl: Signals,
    lead: int,
    axis: Signals,
    out: Signals,
    measured: float,
) -> None:  # pragma: no cover
    """The whole run with a compiled model (``step[0]`` on ``model = (params, state,
    gms)``, a strategy's first-class compiled step) and the direct link."""
    buffer, delay, hold = link
    params, state, g = model
    model_step = step[0]
    for k in range(ref[0].size):
        wanted = 0.0
        if has_observer:
            x, v = _observer_input(k, ref, look_ahead, feed_measured, measured, ctrl)
            force = model_step(params, state, g, x, v)
            wanted = _feedforward(k, force, obs, ref, axis, inertial_gain, ctrl)
        ff = delayed_hold(buffer, delay, hold, k, wanted)
        measured = _actuate(k, ff, measured, ref, lead, ctrl, axis, out)


def run(
    reference: Reference,
    axis: LinearMotorAxis,
    controller: CascadeController,
    link: FeedforwardLink,
    observer: FrictionObserver | None = None,
    feed: Literal["reference", "measured"] = "reference",
    look_ahead_cycles: int = 0,
) -> RunResult:
    """Run ``reference`` once from rest; ``observer=None`` means no compensation.

    With a :class:`DirectLink` and a compiled model (or none) the whole run is one
    compiled call; otherwise (a Python link such as the CAN bridge, a model with
    Python parts) the same compiled steps are called once per cycle from Python.
    """
    n = reference.cycles
    axis.reset(n + 1)
    controller.reset(axis.position_m)
    if observer is not None:
        observer.reset()
    ref = (reference.position_m, reference.velocity_m_s, reference.acceleration_m_s2)
    out = tuple(np.zeros(n) for _ in range(4))
    ctrl = (controller.gains, controller.state)
    plant = axis.compiled()
    obs = (
        (observer.state, observer.params)
        if observer is not None
        else (np.zeros(5), np.zeros(PARAMS))
    )
    inertial_gain = axis.cfg.moving_mass_kg / axis.cfg.force_constant_N_per_A
    lead = controller.acceleration_lead_cycles
    feed_measured = feed == "measured"
    model = compiled_model(observer.model) if observer is not None else _NO_MODEL
    measured = axis.measure()
    if isinstance(link, DirectLink) and model is not None:
        compiled_link = (link.buffer, link.delay_cycles, link.hold_cycles)
        with warnings.catch_warnings():  # first-class functions are "experimental" in numba
            warnings.simplefilter("ignore", numba.NumbaExperimentalFeatureWarning)
            _run_compiled(
                ref, (model.step,), (model.params, model.state, model.gms), observer is not None,
                obs, look_ahead_cycles, feed_measured, inertial_gain, compiled_link, ctrl, lead,
                plant, out, measured,
            )  # fmt: skip
    else:
        for k in range(n):
            wanted = 0.0
            if observer is not None:
                x, v = _observer_input(k, ref, look_ahead_cycles, feed_measured, measured, ctrl)
                force = observer.model.step(x, v)
                wanted = _feedforward(k, force, obs, ref, plant, inertial_gain, ctrl)
            ff = link.transfer(k, wanted)
            measured = _actuate(k, ff, measured, ref, lead, ctrl, plant, out)
    return RunResult(reference, *out)
