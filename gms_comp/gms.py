"""The Generalized Maxwell-Slip (GMS) friction model, batch and streaming.

Al-Bender, Lampaert, Swevers, IEEE TAC 50(11), 2005. The friction force is

    F = sum_i F_i + sigma2 v,

with N elements (stiffness k_i, stick limit W_i). Element i sticks,
dF_i = k_i dx, while |F_i| <= W_i; beyond, it slips, and its force is attracted
to the slip force sgn(v) s(v) W_i by dF_i/dt = sgn(v) (C / s) (s W_i - F_i),
until the motion reverses; it then sticks again from +-W_i. The velocity level

    s(v) = C_v + (1 - C_v) exp(-(|v| / v_t)^delta)

is 1 at rest and C_v when moving (the seed's Gaussian at delta = 2; with a finite
``transition_tail`` p, exp(-q) is (1 + q / p)^-p, q = (|v| / v_t)^delta: at p = 1,
delta = 2, Hess and Soom's Lorentzian, approaching C_v algebraically). The seed's bristle
law (its Eq. 1): a stuck bristle carries k u up to f_max, a slipping one C_v f_max, so
the force drops by C_v at a stop and at a reversal, and comes back when slipping resumes.
C_v > 1 is the seed's slip exaggeration; C_v < 1 gives stiction with a Stribeck drop.
With C_v = 1 it is Al-Bender's GMS with a constant level.

With ``limit_follows_level`` the stick limit is s(v) W_i itself (a play operator of width
s(v) W_i / k_i, an independent reading of "C_v maps to a velocity-dependent limit"): a
slipping element climbs from W_i to s W_i over (s - 1) W_i / k_i more travel, not at once.

The update is per displacement step (dt = |dx| / |v|): the attraction is the exact factor
exp(-C |dx| / (s |v|)) left of a slipping element's distance to its target; for C = inf
(the default) 0, and the stick part is the exact, unconditionally stable play-operator
update F_i <- clip(F_i + k_i dx, -W_i, W_i). A sample at rest applies the new level at once.

One numba per-sample routine serves both: :func:`simulate` loops it, :class:`GmsStream` steps it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Literal

import numba
import numpy as np
from numpy.typing import ArrayLike

from gms_comp.arrays import FloatArray

# Layout of the scalar parameter vector handed to the kernels.
_SLIP_LEVEL, _TRANSITION_V, _TRANSITION_EXP, _ATTRACTION, _VISCOUS = range(5)
_TRANSITION_TAIL, _PLAY = 5, 6


@dataclass(frozen=True, eq=False)
class GmsParams:
    """Parameters of a GMS model; SI units.

    Parameters
    ----------
    stiffness_N_per_m
        Element stiffnesses k_i, shape (N,), all > 0.
    limit_N
        Element stick limits W_i, shape (N,), all >= 0.
    slip_level
        C_v: slip force of a moving element relative to its stick limit (seed: 1.2).
    transition_velocity_m_s
        v_t: speed over which s moves from 1 to ``slip_level``.
    transition_exponent
        delta: shape of that transition (2: Gaussian, 1: exponential).
    transition_tail
        p: ``inf``, the exponential approach; finite, (1 + q / p)^-p, q = (|v| / v_t)^delta.
    limit_follows_level
        False: the seed's law (stick up to W_i, slip at s W_i); True: stick up to s W_i
        (then ``attraction_rate_per_s`` must be inf).
    attraction_rate_per_s
        C: rate at which a slipping element is drawn to its limit; ``inf``
        gives the rate-independent Maxwell-slip model.
    viscous_Ns_per_m
        sigma2: viscous coefficient.
    """

    stiffness_N_per_m: FloatArray
    limit_N: FloatArray
    slip_level: float = 1.0
    transition_velocity_m_s: float = 1e-4
    transition_exponent: float = 2.0
    attraction_rate_per_s: float = math.inf
    viscous_Ns_per_m: float = 0.0
    transition_tail: float = math.inf
    limit_follows_level: bool = False

    def __post_init__(self) -> None:
        k = _frozen_vector(self.stiffness_N_per_m)
        w = _frozen_vector(self.limit_N)
        if k.shape != w.shape or k.size == 0:
            raise ValueError(
                f"stiffness_N_per_m and limit_N must have the same non-zero length, "
                f"got {k.size} and {w.size}"
            )
        finite = math.isfinite
        checks = {
            "stiffness_N_per_m": bool(np.all(k > 0)),
            "limit_N": bool(np.all(w >= 0)),
            "slip_level": finite(self.slip_level) and self.slip_level > 0,
            "transition_velocity_m_s": finite(self.transition_velocity_m_s)
            and self.transition_velocity_m_s > 0,
            "transition_exponent": finite(self.transition_exponent)
            and self.transition_exponent > 0,
            "attraction_rate_per_s": self.attraction_rate_per_s > 0,  # inf allowed
            "transition_tail": self.transition_tail > 0,  # inf allowed
            "limit_follows_level": isinstance(self.limit_follows_level, bool),
            "viscous_Ns_per_m": finite(self.viscous_Ns_per_m) and self.viscous_Ns_per_m >= 0,
        }
        for name, ok in checks.items():
            if not ok:
                raise ValueError(f"GmsParams.{name} is out of range: {getattr(self, name)!r}")
        if self.limit_follows_level and math.isfinite(self.attraction_rate_per_s):
            raise ValueError("GmsParams.limit_follows_level has no attraction_rate_per_s")
        object.__setattr__(self, "stiffness_N_per_m", k)
        object.__setattr__(self, "limit_N", w)

    @property
    def n_elements(self) -> int:
        """Number of Maxwell-slip elements."""
        return int(self.stiffness_N_per_m.size)

    @property
    def scalars(self) -> FloatArray:
        """The scalar parameters in the order the kernels expect."""
        return np.array(
            [
                self.slip_level,
                self.transition_velocity_m_s,
                self.transition_exponent,
                self.attraction_rate_per_s,
                self.viscous_Ns_per_m,
                self.transition_tail,
                float(self.limit_follows_level),
            ]
        )

    def level(self, velocity_m_s: ArrayLike) -> FloatArray:
        """The velocity level s(v) (1 at rest, ``slip_level`` when moving)."""
        u = np.abs(np.asarray(velocity_m_s, dtype=float)) / self.transition_velocity_m_s
        p = u**self.transition_exponent
        tail = self.transition_tail
        approach = np.exp(-p if math.isinf(tail) else -tail * np.log1p(p / tail))
        return self.slip_level + (1.0 - self.slip_level) * approach

    def virgin_curve(self, displacement_m: ArrayLike, level: float = 1.0) -> FloatArray:
        """Force after a monotone displacement from the virgin state at a fixed level (no
        viscous part): sign(x) sum_i k_i phi_i(|x|), phi_i(u) = u up to d_i = W_i / k_i, then
        level d_i (the seed's law) or min(u, level d_i) (``limit_follows_level``)."""
        x = np.asarray(displacement_m, dtype=float)
        u, d = np.abs(x)[:, None], (self.limit_N / self.stiffness_N_per_m)[None, :]
        seed = np.where(u <= d, u, level * d)
        shape = np.minimum(u, level * d) if self.limit_follows_level else seed
        return np.sign(x) * (shape @ self.stiffness_N_per_m)


def scaled(params: GmsParams, level: float, presliding: float, **fields: Any) -> GmsParams:
    """``params`` with every W_i times ``level`` and every break-away W_i / k_i times
    ``presliding`` (and any scalar field replaced). A zero level keeps k_i > 0."""
    w = params.limit_N * level
    k = params.stiffness_N_per_m * (max(level, 1e-300) / presliding)
    return dataclasses.replace(params, stiffness_N_per_m=k, limit_N=w, **fields)


def _frozen_vector(values: ArrayLike) -> FloatArray:
    arr = np.array(values, dtype=np.float64).reshape(-1)
    if not np.all(np.isfinite(arr)):
        raise ValueError("GMS element parameters must be finite")
    arr.flags.writeable = False
    return arr


@dataclass
class GmsState:
    """Persistent state of a GMS model between calls.

    ``element_force_N``: F_i; ``slip_direction``: +1/-1 while element i slips
    in that direction, 0 while it sticks; ``position_m``: the last position
    seen (NaN before the first sample).
    """

    element_force_N: FloatArray
    slip_direction: FloatArray
    position_m: float = math.nan

    @classmethod
    def virgin(cls, n_elements: int) -> GmsState:
        """All elements unloaded and sticking."""
        return cls(np.zeros(n_elements), np.zeros(n_elements))

    def copy(self) -> GmsState:
        """An independent copy of this state."""
        return GmsState(self.element_force_N.copy(), self.slip_direction.copy(), self.position_m)


# --- the kernel -----------------------------------------------------------------------

# Reassociation lets the element sum vectorise; no "nnan"/"ninf", which would drop the
# NaN and inf checks the kernel relies on.
_FAST = {"reassoc", "contract", "nsz", "arcp"}


@numba.njit(cache=True, inline="always")
def _level(speed: float, scalars: FloatArray) -> float:
    u = speed / scalars[_TRANSITION_V]
    # The Gaussian shape is the default; avoid pow() on the hot path for it.
    p = u * u if scalars[_TRANSITION_EXP] == 2.0 else u ** scalars[_TRANSITION_EXP]
    tail = scalars[_TRANSITION_TAIL]
    approach = math.exp(-p if math.isinf(tail) else -tail * math.log1p(p / tail))
    return scalars[_SLIP_LEVEL] + (1.0 - scalars[_SLIP_LEVEL]) * approach


@numba.njit(cache=True, inline="always")
def _sample(dx: float, speed: float, scalars: FloatArray) -> tuple[float, float]:
    """The level s(v) of a sample and the fraction of a slipping element's distance to
    its target left after it: exp(-C dt / s) with dt = |dx| / |v|; 0 at rest or for
    C = inf."""
    level = _level(speed, scalars)
    rate = scalars[_ATTRACTION]
    if speed == 0.0 or math.isinf(rate):
        return level, 0.0
    return level, math.exp(-rate * abs(dx) / (level * speed))


@numba.njit(cache=True, inline="always")
def _element(
    f: float, d: float, k: float, limit: float, dx: float, level: float, remain: float, play: float
) -> tuple[float, float]:
    """Element force and slip direction after a step ``dx`` (branch-free, so that the
    element loops vectorise; ``play``: the limit follows the level)."""
    if play != 0.0:
        bound = level * limit
        moved = f + k * dx
        return min(max(moved, -bound), bound), (moved > bound) * 1.0 - (moved < -bound) * 1.0
    slipping = (d * dx >= 0.0) & (d != 0.0)
    # An element leaving slip (a reversal) restarts from its stick limit.
    stick = (f if d == 0.0 else d * limit) + k * dx
    entering = (stick > limit) * 1.0 - (stick < -limit) * 1.0
    direction = d if slipping else entering
    target = direction * level * limit
    start = f if slipping else direction * limit
    clipped = min(max(stick, -limit), limit)
    return (target + (start - target) * remain if direction != 0.0 else clipped), direction


@numba.njit(cache=True, fastmath=_FAST)
def _run(
    stiffness: FloatArray,
    limits: FloatArray,
    scalars: FloatArray,
    forces: FloatArray,
    slips: FloatArray,
    last_position: float,
    position: FloatArray,
    velocity: FloatArray,
    out: FloatArray,
) -> None:
    """Advance the elements sample by sample; the state arrays are updated in place."""
    # Fresh local copies: the compiler then knows they alias nothing and vectorises
    # the element loop (which is also why that loop is written branch-free).
    k = stiffness.copy()
    w = limits.copy()
    f = forces.copy()
    d = slips.copy()
    previous = position[0] if math.isnan(last_position) else last_position
    play = scalars[_PLAY]
    for j in range(position.size):
        dx = position[j] - previous
        previous = position[j]
        level, remain = _sample(dx, abs(velocity[j]), scalars)
        total = 0.0
        for i in range(k.size):
            f[i], d[i] = _element(f[i], d[i], k[i], w[i], dx, level, remain, play)
            total += f[i]
        out[j] = total + scalars[_VISCOUS] * velocity[j]
    forces[:] = f
    slips[:] = d


@numba.njit(cache=True, fastmath=_FAST)
def _run_elements(
    stiffness: FloatArray,
    limits: FloatArray,
    scalars: FloatArray,
    position: FloatArray,
    velocity: FloatArray,
    out: FloatArray,
) -> None:
    """:func:`_run` from the virgin state, each element's force in a column of ``out``
    (the level and attraction of a sample computed once for all elements)."""
    k = stiffness.copy()
    w = limits.copy()
    f = np.zeros(k.size)
    d = np.zeros(k.size)
    previous = position[0]
    play = scalars[_PLAY]
    for j in range(position.size):
        dx = position[j] - previous
        previous = position[j]
        level, remain = _sample(dx, abs(velocity[j]), scalars)
        for i in range(k.size):
            f[i], d[i] = _element(f[i], d[i], k[i], w[i], dx, level, remain, play)
            out[j, i] = f[i]


# --- the two interfaces ---------------------------------------------------------------


def _path(position_m: ArrayLike, velocity_m_s: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Position and velocity as contiguous float64 vectors of one length."""
    x = np.ascontiguousarray(position_m, dtype=np.float64)
    v = np.ascontiguousarray(velocity_m_s, dtype=np.float64)
    if x.ndim != 1 or x.shape != v.shape:
        raise ValueError(
            f"position_m and velocity_m_s must be 1-D of equal length, got {x.shape} and {v.shape}"
        )
    return x, v


def simulate(
    params: GmsParams, position_m: ArrayLike, velocity_m_s: ArrayLike,
    state: GmsState | None = None,
) -> tuple[FloatArray, GmsState]:  # fmt: skip
    """Friction force along a sampled trajectory, and the state after its last sample.

    ``position_m``, ``velocity_m_s``: samples of one length; the displacement between
    samples drives the elements, the velocity sets the level s(v), the attraction time
    and the viscous force. ``state``: where to continue from (not modified); ``None``
    starts virgin at the first position.

    Examples
    --------
    >>> p = GmsParams(np.array([1e6]), np.array([0.1]))
    >>> f, _ = simulate(p, [0.0, 5e-8, 1e-6], [0.0, 1e-3, 1e-3])
    >>> np.round(f, 3).tolist()
    [0.0, 0.05, 0.1]
    """
    x, v = _path(position_m, velocity_m_s)
    new = GmsState.virgin(params.n_elements) if state is None else state.copy()
    out = np.empty_like(x)
    if x.size:
        _run(
            params.stiffness_N_per_m,
            params.limit_N,
            params.scalars,
            new.element_force_N,
            new.slip_direction,
            new.position_m,
            x,
            v,
            out,
        )
        new.position_m = float(x[-1])
    return out, new


def simulate_elements(
    params: GmsParams, position_m: ArrayLike, velocity_m_s: ArrayLike, spare: int = 0,
    order: Literal["C", "F"] = "C",
) -> FloatArray:  # fmt: skip
    """Each element's force along a sampled trajectory from the virgin state, shape
    (samples, elements): :func:`simulate`'s force is their row sums plus the viscous
    force. One pass for all elements (the diagnosis's and the reduction's basis columns).
    With ``spare``, that many more columns follow, not set: for the caller's own columns
    of one design (stacked afterwards, they cost a copy of the whole design). With
    ``order`` "F" each element's column is contiguous (a third slower to fill for a dozen
    elements, four times faster to read one column of).

    Examples
    --------
    >>> p = GmsParams(np.array([1e6, 1e5]), np.array([0.1, 0.1]))
    >>> np.round(simulate_elements(p, [0.0, 5e-8, 1e-6], [0.0, 1e-3, 1e-3]), 3).tolist()
    [[0.0, 0.0], [0.05, 0.005], [0.1, 0.1]]
    """
    x, v = _path(position_m, velocity_m_s)
    out = np.empty((x.size, params.n_elements + spare), order=order)
    if x.size:
        _run_elements(params.stiffness_N_per_m, params.limit_N, params.scalars, x, v, out)
    return out


class GmsStream:
    """Per-sample GMS for a real-time loop, with persistent state.

    Each :meth:`step` runs the batch kernel on one-sample buffers allocated once,
    so the streaming and batch results are identical. The parameters, state and
    buffers form one tuple, :attr:`kernel`, that :func:`stream_step` advances in
    place: another numba kernel (the simulator's compiled loop) steps the same
    stream through it.

    Examples
    --------
    >>> s = GmsStream(GmsParams(np.array([1e6]), np.array([0.1])))
    >>> round(s.step(0.0, 0.0), 3), round(s.step(1e-6, 1e-3), 3)
    (0.0, 0.1)
    """

    def __init__(self, params: GmsParams) -> None:
        self.params = params
        n = params.n_elements
        # (k, W, scalars, F_i, slip directions, last position, x, v, force buffers)
        self.kernel = (
            params.stiffness_N_per_m,
            params.limit_N,
            params.scalars,
            np.zeros(n),
            np.zeros(n),
            np.full(1, math.nan),
            np.zeros(1),
            np.zeros(1),
            np.zeros(1),
        )

    @property
    def state(self) -> GmsState:
        """The current state (its arrays are the stream's own, not copies)."""
        return GmsState(self.kernel[3], self.kernel[4], float(self.kernel[5][0]))

    def reset(self) -> None:
        """Back to the virgin state; the next sample sets the reference position."""
        self.kernel[3][:] = 0.0
        self.kernel[4][:] = 0.0
        self.kernel[5][0] = math.nan

    def step(self, position_m: float, velocity_m_s: float) -> float:
        """Advance one sample and return the friction force in N."""
        return float(stream_step(self.kernel, position_m, velocity_m_s))


@numba.njit(cache=True)
def stream_step(kernel: Any, position_m: float, velocity_m_s: float) -> float:  # pragma: no cover
    """One sample of :func:`_run` on a :attr:`GmsStream.kernel` tuple, in place."""
    k, w, scalars, forces, slips, last, x1, v1, out = kernel
    x1[0] = position_m
    v1[0] = velocity_m_s
    _run(k, w, scalars, forces, slips, last[0], x1, v1, out)
    last[0] = position_m
    return out[0]
