"""Offline reduction of the ball model to a GMS table (non-negative least squares).

With the element breakpoints Delta_i = W_i / k_i fixed, the GMS force along any
path is linear in the stiffnesses: element i contributes k_i g(Delta_i, path),
where g is the force of a unit-stiffness element (its virgin shape is
:func:`gms_comp.gms.element_shape`). So for log-spaced breakpoints the k_i
follow from :func:`scipy.optimize.nnls` on the ball model's virgin curve,
together with the ball model's force along a training path (stops and
reversals of many amplitudes, which the virgin curve alone does not show). The
span of the breakpoints is chosen on a small grid by the least residual.

Fidelity is measured on paths the fit has not seen: the seed's Fig. 7 profile
and a random multi-amplitude path, as RMS and maximum of (GMS - ball model)
relative to the sliding force.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
from scipy.optimize import nnls
from tqdm import tqdm

from .config import BallConfig, config_hash, in_range, parse_section, positive, read_toml
from .gms import FloatArray, GmsParams, element_shape, simulate
from .profiles import seed_fig7_profile
from .table import Fidelity, GmsTable
from .transient import BallSetFriction

Path_ = tuple[FloatArray, FloatArray]
ForceModel = Callable[[FloatArray, FloatArray], FloatArray]


@dataclass(frozen=True)
class TableConfig:
    """The ``[table]`` section: how a GMS table is reduced from the ball model."""

    elements: int = field(default=16, metadata=in_range(1, 1024))
    curve: Literal["virgin", "reversal"] = "virgin"
    transition_velocity_m_s: float = field(default=1e-6, metadata=positive())
    transition_exponent: float = field(default=2.0, metadata=positive())
    curve_points: int = field(default=300, metadata=in_range(20, 100_000))
    sample_rate_Hz: float = field(default=20_000.0, metadata=positive())
    random_reversals: int = field(default=30, metadata=in_range(1, 100_000))
    random_seed: int = 0


def load_table_config(path: str | Path) -> TableConfig:
    """The ``[table]`` section of a config file (all keys optional)."""
    return parse_section(read_toml(path), path, "table", TableConfig)


# --- fitting --------------------------------------------------------------------------


def element_responses(
    breakpoints_m: FloatArray, template: GmsParams, position_m: FloatArray, velocity_m_s: FloatArray
) -> FloatArray:
    """Force of each unit-stiffness element (W_i = Delta_i) along a path, shape (T, N)."""
    columns = [
        simulate(_with_elements(template, np.ones(1), np.array([b])), position_m, velocity_m_s)[0]
        for b in breakpoints_m
    ]
    return np.column_stack(columns)


def _with_elements(template: GmsParams, k: FloatArray, w: FloatArray) -> GmsParams:
    return GmsParams(
        k,
        w,
        slip_level=template.slip_level,
        transition_velocity_m_s=template.transition_velocity_m_s,
        transition_exponent=template.transition_exponent,
        attraction_rate_per_s=template.attraction_rate_per_s,
        viscous_Ns_per_m=template.viscous_Ns_per_m,
    )


def fit_elements(
    breakpoints_m: FloatArray,
    template: GmsParams,
    curve: tuple[FloatArray, FloatArray],
    paths: Iterable[tuple[Path_, FloatArray]] = (),
) -> tuple[GmsParams, float]:
    """NNLS stiffnesses for fixed breakpoints; returns the model and the RMS residual.

    ``curve`` is (displacement, force) of the virgin curve; ``paths`` are
    ((position, velocity), force) samples of the reference along paths. Elements
    whose stiffness comes out zero are dropped.
    """
    x, f = curve
    rows = [element_shape(x, breakpoints_m, template.slip_level)]
    targets = [f]
    for (pos, vel), force in paths:
        rows.append(element_responses(breakpoints_m, template, pos, vel))
        targets.append(force - template.viscous_Ns_per_m * vel)
    a, b = np.vstack(rows), np.concatenate(targets)
    k, residual = nnls(a, b)
    keep = k > 0
    model = _with_elements(template, k[keep], k[keep] * breakpoints_m[keep])
    return model, float(residual / np.sqrt(b.size))


def fit_span(
    n_elements: int,
    template: GmsParams,
    curve: tuple[FloatArray, FloatArray],
    paths: list[tuple[Path_, FloatArray]],
    spans_m: Iterable[tuple[float, float]],
) -> GmsParams:
    """Best fit over candidate breakpoint spans (first, last breakpoint)."""
    best: tuple[float, GmsParams] | None = None
    for lo, hi in spans_m:
        bp = np.geomspace(lo, hi, n_elements)
        model, residual = fit_elements(bp, template, curve, paths)
        if best is None or residual < best[0]:
            best = (residual, model)
    assert best is not None, "no candidate spans"
    return best[1]


def candidate_spans(x_m: FloatArray, force_N: FloatArray) -> list[tuple[float, float]]:
    """Breakpoint spans around where the virgin curve bends: from 1 % to 99.9 % of its end."""
    end = abs(force_N[-1])
    first = float(x_m[np.argmax(np.abs(force_N) >= 0.01 * end)])
    last = float(x_m[np.argmax(np.abs(force_N) >= 0.999 * end)])
    los = first * np.geomspace(0.1, 3.0, 6)
    his = last * np.geomspace(0.1, 1.5, 6)
    return [(lo, hi) for lo, hi in itertools.product(los, his) if hi > 2 * lo]


# --- fidelity -------------------------------------------------------------------------


def fidelity(
    params: GmsParams, references: Iterable[tuple[Path_, FloatArray]], sliding_force_N: float
) -> Fidelity:
    """RMS and maximum of (GMS - reference) over the paths, relative to the sliding force."""
    errors = np.concatenate(
        [simulate(params, pos, vel)[0] - force for (pos, vel), force in references]
    )
    return Fidelity(
        rms_rel=float(np.sqrt(np.mean(errors**2)) / sliding_force_N),
        max_rel=float(np.max(np.abs(errors)) / sliding_force_N),
    )


def random_path(
    rng: np.random.Generator,
    reversals: int,
    amplitude_range_m: tuple[float, float],
    speed_m_s: float,
    sample_rate_Hz: float,
) -> Path_:
    """Constant-speed moves of log-uniform random amplitude and direction, some with stops."""
    step = speed_m_s / sample_rate_Hz
    xs, vs = [np.zeros(1)], [np.zeros(1)]
    position = 0.0
    lo, hi = np.log10(amplitude_range_m)
    for _ in range(reversals):
        move = 10 ** rng.uniform(lo, hi) * rng.choice([-1.0, 1.0])
        n = max(2, int(np.ceil(abs(move) / step)))
        xs.append(position + np.linspace(0.0, move, n + 1)[1:])
        vs.append(np.full(n, np.sign(move) * speed_m_s))
        position += move
        if rng.random() < 0.3:  # a stop: the level drops to the stick limit
            xs.append(np.full(20, position))
            vs.append(np.zeros(20))
    return np.concatenate(xs), np.concatenate(vs)


def with_reference(model: ForceModel, paths: Iterable[Path_]) -> list[tuple[Path_, FloatArray]]:
    return [((x, v), model(x, v)) for x, v in paths]


# --- the ball model ---------------------------------------------------------------------


def reduce_to_gms(
    cfg: BallConfig,
    n_elements: int | None = None,
    table_cfg: TableConfig | None = None,
    *,
    progress: bool = False,
) -> GmsTable:
    """Reduce the configured ball set to an N-element GMS table.

    Parameters
    ----------
    cfg
        The physics config (its file is hashed into the table).
    n_elements
        N; default ``table_cfg.elements``.
    table_cfg
        Reduction settings; default: the ``[table]`` section of ``cfg.path``.
    progress
        Show a progress bar on stderr.
    """
    tc = table_cfg if table_cfg is not None else load_table_config(cfg.path)
    n = n_elements if n_elements is not None else tc.elements
    with tqdm(total=4, desc="gms table", disable=not progress, leave=False) as bar:
        ball = BallSetFriction(cfg)
        template = GmsParams(
            np.ones(1),
            np.ones(1),
            slip_level=cfg.bearing.slip_exaggeration,
            transition_velocity_m_s=tc.transition_velocity_m_s,
            transition_exponent=tc.transition_exponent,
        )
        curve = _ball_curve(ball, tc)
        bar.update()
        speed = cfg.stand.carriage_velocity_m_s
        presliding_m = float(curve[0][np.argmax(curve[1] >= 0.999 * curve[1][-1])])
        amplitudes = (0.01 * presliding_m, 3.0 * presliding_m)
        rng = np.random.default_rng(tc.random_seed)
        training, test = (
            random_path(rng, tc.random_reversals, amplitudes, speed, tc.sample_rate_Hz)
            for _ in range(2)
        )
        _t, fig7_x, fig7_v = seed_fig7_profile(tc.sample_rate_Hz, velocity_m_s=speed)
        train_refs = with_reference(ball.force, [training])
        test_refs = with_reference(ball.force, [(fig7_x, fig7_v), test])
        bar.update()
        params = fit_span(n, template, curve, train_refs, candidate_spans(*curve))
        bar.update()
        quality = fidelity(params, test_refs, ball.sliding_force_N)
        bar.update()
    return GmsTable(
        params=params,
        source_config=str(cfg.path),
        source_sha256=config_hash(cfg.path),
        fidelity=quality,
    )


def _ball_curve(ball: BallSetFriction, tc: TableConfig) -> tuple[FloatArray, FloatArray]:
    """The virgin curve, or half the reversal curve at twice the displacement (Masing)."""
    x = np.geomspace(1e-10, 1e-2, tc.curve_points)
    if tc.curve == "virgin":
        return x, ball.virgin_curve(x)
    reversal = ball.reversal_curve(np.concatenate([[0.0], 2.0 * x]))
    return x, 0.5 * (reversal[1:] - reversal[0])
