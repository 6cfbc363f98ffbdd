"""The interface of a catalogue effect: its form, parameters and basis columns.

An additive effect is a linear combination of *basis* columns whose shape depends on a
few nonlinear parameters (the ripple's wavelength, the transient's length, ...):
``force + basis(ctx, shape) @ coefficients``. The diagnosis fits the coefficients over
those same columns (its bounds, grids and judgement are the effect's diagnosis policy,
:mod:`gms_comp.measured.policies`), so a fitted effect and the one applied afterwards are
one formula. A :class:`FilterEffect` is a linear filter of the whole force instead.

The forms that scale the friction (stribeck, dwell_time, drift) act on the GMS force
``ctx.gms_force_N``: in steady sliding a GMS force equals its element limits times the
velocity level, so scaling the force is scaling the limits; at a break-away it scales the
peak. That keeps the GMS kernel (:mod:`gms_comp.gms`) untouched.

Adding an effect: one module in this package with a subclass of :class:`Effect` (its
form and parameters) and one line in ``CATALOGUE`` (``__init__``), plus its diagnosis
policy beside the diagnosis.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import MISSING, dataclass, fields
from typing import ClassVar, Protocol

import numba
import numpy as np
from scipy import signal

from gms_comp.arrays import FloatArray
from gms_comp.gms import GmsParams
from gms_comp.runtime.effects.path import Context

Shape = dict[str, float]

# A filter steps this many columns or more together (:func:`_filter_columns`); fewer are
# filtered one by one (for one to four columns of 188 000 rows, 1.6-8 ms against 6-10).
STEPPED_TOGETHER = 8


@dataclass(frozen=True)
class Effect:
    """Base of the catalogue: ``force + basis(ctx, shape) @ coefficients``.

    Subclasses name their nonlinear shape parameters in ``SHAPE`` and map between the
    basis coefficients and their named parameters.
    """

    name: ClassVar[str]
    SHAPE: ClassVar[tuple[str, ...]] = ()
    # An effect of the measurement chain, not of the contact: a compensator does not add it.
    measurement_only: ClassVar[bool] = False

    @classmethod
    def basis(cls, ctx: Context, shape: Mapping[str, float]) -> FloatArray:
        """Design columns of the effect along ``ctx`` for the shape parameters ``shape``."""
        raise NotImplementedError

    @classmethod
    def from_coefficients(cls, coefficients: FloatArray, shape: Mapping[str, float]) -> Effect:
        """The effect whose basis coefficients are ``coefficients``."""
        raise NotImplementedError

    def coefficients(self) -> FloatArray:
        """The basis coefficients of this effect."""
        raise NotImplementedError

    def shape(self) -> Shape:
        """The shape parameters of this effect."""
        return {k: getattr(self, k) for k in self.SHAPE}

    def parameters(self) -> dict[str, float]:
        """All parameters by their spec names, SI units; an optional one (a field with a
        default) only where it differs from it, so that older readers read the table."""
        return {
            f.name: float(getattr(self, f.name))
            for f in fields(self)
            if f.default is MISSING or getattr(self, f.name) != f.default
        }

    def apply(self, ctx: Context, force_N: FloatArray) -> FloatArray:
        """The measured force this effect makes of ``force_N`` (batch)."""
        return force_N + self.basis(ctx, self.shape()) @ self.coefficients()

    def stream(self, gms: GmsParams | None) -> Stateful | None:
        """The per-sample form of an effect whose force depends on more history than the
        path quantities hold (its own state, advanced by each one-sample context), or
        None: :meth:`apply` on each sample's context is the effect."""
        return None


class Stateful(Protocol):
    """A per-sample effect with its own state (:meth:`Effect.stream`)."""

    def run(self, ctx: Context) -> FloatArray:
        """The effect's extra force along ``ctx``, continuing from the state."""
        ...

    def step(
        self, position_m: float, velocity_m_s: float, resting: float, dwell_s: float,
        direction: float,
    ) -> float:  # fmt: skip
        """One sample of :meth:`run` (the path's rest flag, dwell and direction at that
        sample)."""
        ...


@dataclass(frozen=True)
class FilterEffect(Effect):
    """An effect that is a linear filter of the whole force (applied after the others)."""

    @classmethod
    def from_shape(cls, shape: Mapping[str, float]) -> FilterEffect:
        """The filter with the parameters ``shape`` (a filter has no coefficients)."""
        raise NotImplementedError

    def filter(self, sample_time_s: float) -> tuple[FloatArray, FloatArray]:
        """Numerator and denominator of the discrete filter."""
        raise NotImplementedError

    def apply(self, ctx: Context, force_N: FloatArray) -> FloatArray:
        """The filtered force."""
        return self.filter_columns(force_N, ctx.sample_time_s)

    def filter_columns(self, x: FloatArray, sample_time_s: float) -> FloatArray:
        """Filter along axis 0, starting at rest at the first sample's value."""
        b, a = self.filter(sample_time_s)
        zi = signal.lfilter_zi(b, a)
        if np.ndim(x) == 1:
            return np.asarray(signal.lfilter(b, a, x, zi=zi * x[0])[0])
        if x.shape[1] < STEPPED_TOGETHER:
            # each column as a contiguous row (1.5-3 x faster than along axis 0)
            rows = np.ascontiguousarray(np.asarray(x).T)
            y, _ = signal.lfilter(b, a, rows, axis=-1, zi=np.multiply.outer(rows[:, 0], zi))
            return np.asarray(y).T
        # a design's columns, filtered for every filter tried on them, all at once: one
        # pass that steps them together is 3-4 x faster than lfilter along each
        m = max(b.size, a.size)
        b, a = (np.pad(c / a[0], (0, m - c.size)) for c in (b, a))
        x = np.ascontiguousarray(x, dtype=np.float64)
        return _filter_columns(b, a, x, np.multiply.outer(zi, x[0])) if m > 1 else b[0] * x


@numba.njit(cache=True)
def _filter_columns(b: FloatArray, a: FloatArray, x: FloatArray, z: FloatArray) -> FloatArray:
    """``scipy.signal.lfilter(b, a, x, axis=0, zi=z)``'s output (its direct form II
    transposed, the same operations in the same order: the same numbers) for a
    normalised filter (``a[0]`` 1, ``b`` and ``a`` of one length m > 1), the state ``z``
    (m - 1, k) of every column of ``x`` (n, k) stepped together sample by sample."""
    n, k = x.shape
    m = b.size
    y = np.empty_like(x)
    z = z.copy()
    w = np.empty_like(z)
    for t in range(n):
        xt, yt = x[t], y[t]
        for j in range(k):
            yt[j] = b[0] * xt[j] + z[0, j]
        for i in range(m - 2):
            zn, wi = z[i + 1], w[i]
            for j in range(k):
                wi[j] = b[i + 1] * xt[j] + zn[j] - a[i + 1] * yt[j]
        wl = w[m - 2]
        for j in range(k):
            wl[j] = b[m - 1] * xt[j] - a[m - 1] * yt[j]
        z, w = w, z
    return y
