"""Applying a list of effects to a GMS force: batch (:func:`apply_extensions`) and per
sample (:class:`ExtensionStream`), equal to each other on a causal context (one dated in
hindsight, as the diagnosis fits on, differs within the deadband's latency after each
reversal: :mod:`.path`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy import signal

from gms_comp.gms import GmsParams
from gms_comp.runtime.effects.base import Effect, FilterEffect
from gms_comp.runtime.effects.path import (
    DEFAULT_STANDSTILL_SPEED_M_S,
    N_OUT,
    Context,
    FloatArray,
    fresh_path_state,
    path_step,
)


def apply_extensions(extensions: Sequence[Effect], ctx: Context) -> FloatArray:
    """The measured force: the GMS force plus every additive effect, then any filter."""
    force = ctx.gms_force_N.copy()
    for effect in extensions:
        if not isinstance(effect, FilterEffect):
            force = effect.apply(ctx, force)
    for effect in extensions:
        if isinstance(effect, FilterEffect):
            force = effect.apply(ctx, force)
    return force


class ExtensionStream:
    """Per-sample application of a list of effects, equal to :func:`apply_extensions`."""

    def __init__(
        self,
        extensions: Sequence[Effect],
        sample_time_s: float,
        standstill_speed_m_s: float = DEFAULT_STANDSTILL_SPEED_M_S,
        reversal_deadband_m: float = 0.0,
        rest_band_m: float = 0.0,
        gms: GmsParams | None = None,
    ) -> None:
        self.extensions = tuple(extensions)
        self.gms = gms
        self.sample_time_s = sample_time_s
        self.standstill_speed_m_s = standstill_speed_m_s
        self.reversal_deadband_m = reversal_deadband_m
        self.rest_band_m = rest_band_m
        self._filters = [
            e.filter(sample_time_s) for e in self.extensions if isinstance(e, FilterEffect)
        ]
        self.reset()

    def reset(self) -> None:
        """Forget the path and the filters' state (a new trajectory)."""
        self._path = fresh_path_state()
        self._row = np.empty((1, N_OUT))
        self._zi: list[FloatArray] | None = None
        # effects with their own state (dwell_time's raised elements), fresh
        self._stateful = [e.stream(self.gms) for e in self.extensions]

    def step(
        self,
        time_s: float,
        position_m: float,
        velocity_m_s: float,
        acceleration_m_s2: float,
        gms_force_N: float,
    ) -> float:
        """The extended force for one sample."""
        path_step(self._path, time_s, position_m, velocity_m_s, self.standstill_speed_m_s,
                  self.reversal_deadband_m, self.rest_band_m, self._row[0])  # fmt: skip
        ctx = Context.with_path(
            np.array([time_s]), np.array([position_m]), np.array([velocity_m_s]),
            np.array([acceleration_m_s2]), np.array([gms_force_N]), self._row,
            self.sample_time_s, self.gms,
        )  # fmt: skip
        force = gms_force_N
        for effect, stateful in zip(self.extensions, self._stateful, strict=True):
            if stateful is not None:
                force += stateful.step(position_m, velocity_m_s, float(ctx.resting[0]),
                                       float(ctx.dwell_s[0]), float(ctx.direction[0]))  # fmt: skip
            elif not isinstance(effect, FilterEffect):
                force = float(effect.apply(ctx, np.array([force]))[0])
        if self._zi is None:  # start at rest at the first value, as the batch filter does
            self._zi = [signal.lfilter_zi(b, a) * force for b, a in self._filters]
        for i, (b, a) in enumerate(self._filters):
            y, self._zi[i] = signal.lfilter(b, a, [force], zi=self._zi[i])
            force = float(y[0])
        return force
