"""How detectable each hidden effect of an independent trace is beyond a plain GMS baseline.

Independent of ``gms_comp`` (numpy and numba only, on top of ``indepgen``/``indepfriction``).

Definition
----------
For a trace (``case``, ``seed``) let ``truth = baseline(seed)[0]`` and
``effects = make_trace(case, seed).effects``. For each effect ``e``:

1. ``d_e = friction(truth, effects) - friction(truth, effects without e)``: the noise-free
   force (N) that ``e`` adds.
2. GMS columns: the unit-limit element forces (spring / break-away, in [-1, 1]) along the
   truth's motion for break-away displacements on a log grid of 24 values from 0.05 um to
   1 mm plus the truth's own ``breakaway_m``; each limit is scaled per sample by the truth's
   ``velocity_level(|v|, C_v, v_t)`` and clipped as in ``play_operator`` without boost
   (``spring += step``, clipped to +-breakaway * level), with the position steps
   ``np.diff(position, prepend=position[0])`` of ``friction``.
3. ``r_e = d_e - P d_e``, ``P`` the ordinary (unconstrained, so generous to the baseline)
   least-squares projection onto those columns: what a Maxwell-slip baseline with free
   element limits could not absorb.
4. Figures, ``noise`` being the trace's force noise standard deviation: ``rms`` =
   rms(d_e)/noise, ``peak`` = max|d_e|/noise, ``mf`` = ||d_e||/noise (matched-filter SNR),
   ``left`` = ||r_e||/noise (the detectability: matched-filter SNR of the unabsorbed part)
   and ``absorbed`` = 1 - ||r_e||^2/||d_e||^2 (0 when the effect adds no force).
"""

from __future__ import annotations

import numpy as np
from indepfriction import Effect, Truth, friction, velocity_level
from indepgen import baseline, make_trace
from numba import njit

GRID_M = np.geomspace(0.05e-6, 1e-3, 24)  # break-away displacements of the free elements


@njit(cache=True)
def _unit_elements(step: np.ndarray, breakaway: np.ndarray, level: np.ndarray) -> np.ndarray:
    """Unit-limit element forces (samples x elements), all elements in one pass."""
    n, m = step.size, breakaway.size
    out = np.empty((n, m))
    spring = np.zeros(m)
    for k in range(n):
        for j in range(m):
            limit = breakaway[j] * level[k]
            moved = spring[j] + step[k]
            if moved > limit:
                moved = limit
            elif moved < -limit:
                moved = -limit
            spring[j] = moved
            out[k, j] = moved / breakaway[j]
    return out


def gms_columns(truth: Truth, breakaway_m: np.ndarray | None = None) -> np.ndarray:
    """Unit-limit Maxwell-slip element forces along the truth's motion.

    Parameters
    ----------
    truth : Truth
        Motion, ``C_v`` and transition velocity of the baseline.
    breakaway_m : numpy.ndarray, optional
        Break-away displacements (m); by default :data:`GRID_M` plus ``truth.breakaway_m``.

    Returns
    -------
    numpy.ndarray
        Shape (samples, elements): spring / break-away of each element, in [-1, 1].
    """
    if breakaway_m is None:
        breakaway_m = np.concatenate([GRID_M, truth.breakaway_m])
    step = np.diff(truth.position_m, prepend=truth.position_m[0]).astype(float)
    speed = np.abs(truth.velocity_m_s)
    level = velocity_level(speed, truth.C_v, truth.transition_velocity_m_per_s).astype(float)
    result: np.ndarray = _unit_elements(step, np.asarray(breakaway_m, dtype=float), level)
    return result


def unabsorbed(columns: np.ndarray, force_N: np.ndarray) -> np.ndarray:
    """Residual of ``force_N`` after its ordinary least-squares projection onto ``columns``.

    Parameters
    ----------
    columns : numpy.ndarray
        Shape (samples, k), e.g. from :func:`gms_columns`.
    force_N : numpy.ndarray
        Shape (samples,).

    Returns
    -------
    numpy.ndarray
        ``force_N`` less its projection, shape (samples,).
    """
    coefficients = np.linalg.lstsq(columns, force_N, rcond=None)[0]
    residual: np.ndarray = force_N - columns @ coefficients
    return residual


def figures(added_N: np.ndarray, residual_N: np.ndarray, noise_N: float) -> dict[str, float]:
    """The module's figures of one effect (``rms``, ``peak``, ``mf``, ``left``, ``absorbed``).

    Parameters
    ----------
    added_N, residual_N : numpy.ndarray
        The effect's force ``d_e`` and what the GMS columns leave of it, ``r_e``.
    noise_N : float
        Force noise standard deviation.

    Returns
    -------
    dict of str to float
        Figures as defined in the module docstring.
    """
    dd, rr = float(added_N @ added_N), float(residual_N @ residual_N)
    return {
        "rms": float(np.sqrt(dd / added_N.size)) / noise_N,
        "peak": float(np.max(np.abs(added_N))) / noise_N,
        "mf": float(np.sqrt(dd)) / noise_N,
        "left": float(np.sqrt(rr)) / noise_N,
        "absorbed": 1.0 - rr / dd if dd > 0.0 else 0.0,
    }


def detectability(case: str, seed: int, samples: int | None = None) -> dict[str, dict[str, float]]:
    """Detectability figures of each hidden effect of the trace (``case``, ``seed``).

    Parameters
    ----------
    case : str
        One of ``indepgen.CASES``.
    seed : int
        The trace's seed.
    samples : int, optional
        Trace length, passed to both ``make_trace`` and ``baseline`` (default: the seed's).

    Returns
    -------
    dict of str to dict of str to float
        Effect name -> :func:`figures` (empty for ``none``).
    """
    generated = make_trace(case, seed, samples)
    truth = baseline(seed, samples)[0]
    effects: tuple[Effect, ...] = generated.effects
    if not effects:
        return {}
    columns = gms_columns(truth)
    full = friction(truth, effects)
    out: dict[str, dict[str, float]] = {}
    for name, _ in effects:
        added = full - friction(truth, tuple(e for e in effects if e[0] != name))
        out[name] = figures(added, unabsorbed(columns, added), generated.noise_N)
    return out
