"""Offline reduction of the ball model to a GMS table of exactly N elements.

The GMS force along any path is linear in the stiffnesses once the element
breakpoints Delta_i = W_i / k_i and the slip level are fixed: element i
contributes k_i g(Delta_i, path), the force of a unit-stiffness element (its
virgin shape is :func:`element_shape`). The fit works on the
ball model's virgin curve together with its force along a training path
(stops and reversals of many amplitudes, which the virgin curve alone does not
show):

1. Start from equal-force elements: breakpoint i where the virgin curve
   reaches (i + 1/2) / N of its end force, all limits equal. This pattern is
   defined by the curve's shape, so it is the same from one config (load) to
   the next and tables of neighbouring loads can be blended index by index.
2. Refine stiffnesses, breakpoints and the slip level together by bounded
   nonlinear least squares (:func:`scipy.optimize.least_squares`, log
   parameters so every element keeps k_i > 0). Elements come out sorted by
   breakpoint.

The slip level is fitted rather than copied from the seed's C_v because the
ball model's force does not rise by C_v everywhere when it slides: bristles
that entered the contact recently are still stuck (the stick zone behind the
leading edge is part of the steady state of a conveyed field), and only the
saturated ones carry C_v f_max. On Table 1 the steady ratio of sliding to stop
force is 1.186, not 1.2; a GMS, whose every element slips in steady sliding,
matches that with s = 1.186 while moving.

Fidelity is measured on paths the fit has not seen: the seed's Fig. 7 profile
and a random multi-amplitude path, as RMS and maximum of (GMS - ball model)
relative to the sliding force.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
from scipy.optimize import least_squares
from tqdm import tqdm

from gms_comp.arrays import FloatArray
from gms_comp.config import config_hash, in_range, parse_section, read_toml
from gms_comp.errors import ConfigError, InputError
from gms_comp.gms import GmsParams, scaled, simulate, simulate_elements
from gms_comp.physics.config import BallConfig, check_loads
from gms_comp.physics.profiles import seed_fig7_profile
from gms_comp.physics.transient import BallSetFriction
from gms_comp.tables.table import Fidelity, GmsTable, LoadFamily, Scaling
from gms_comp.validation import MAX_FAMILY_LOADS, MAX_SEED, MAX_TABLE_ELEMENTS

Path_ = tuple[FloatArray, FloatArray]
Reference = tuple[Path_, FloatArray]
ForceModel = Callable[[FloatArray, FloatArray], FloatArray]

# Stiffnesses may move this factor away from their start during the refinement; it keeps
# every element alive (k_i > 0 in floating point) without constraining a sensible fit.
_STIFFNESS_RANGE = 1e8
# Relative steps of the finite differences in the Jacobian (log breakpoint, slip level).
_LOG_STEP = 1e-4
_LEVEL_STEP = 1e-4


def element_shape(displacement_m: FloatArray, breakpoint_m: FloatArray, level: float) -> FloatArray:
    """Virgin force per unit stiffness, phi(x, Delta) = x for x <= Delta, else level Delta.

    Shape (len(displacement_m), len(breakpoint_m)); the virgin curve is linear in
    the stiffnesses, which is what the reduction's least squares relies on.
    """
    x = np.asarray(displacement_m, dtype=float)[:, None]
    b = np.asarray(breakpoint_m, dtype=float)[None, :]
    return np.where(x <= b, x, level * b)


@dataclass(frozen=True)
class TableConfig:
    """The ``[table]`` section: how a GMS table is reduced from the ball model.

    ``fit_slip_level`` fits the moving level s between 1 and the seed's C_v
    (otherwise s = C_v); ``refinement_evaluations`` bounds the nonlinear
    refinement; ``family_loads_N`` (ball loads) adds a load family to the table.
    """

    elements: int = field(default=16, metadata=in_range(1, 1024))
    curve: Literal["virgin", "reversal"] = "virgin"
    transition_velocity_m_s: float = field(default=1e-6, metadata=in_range(1e-9, 0.1))
    transition_exponent: float = field(default=2.0, metadata=in_range(0.1, 10.0))
    fit_slip_level: bool = True
    refinement_evaluations: int = field(default=60, metadata=in_range(1, 10_000))
    curve_points: int = field(default=300, metadata=in_range(20, 100_000))
    sample_rate_Hz: float = field(default=20_000.0, metadata=in_range(100.0, 1e6))
    random_reversals: int = field(default=30, metadata=in_range(1, 10_000))
    random_seed: int = field(default=0, metadata=in_range(0, MAX_SEED))
    family_loads_N: tuple[float, ...] = field(
        default=(), metadata=in_range(1e-3, 1e5, max_items=MAX_FAMILY_LOADS)
    )


def load_table_config(path: str | Path) -> TableConfig:
    """The ``[table]`` section of a config file (all keys optional)."""
    return parse_section(read_toml(path), path, "table", TableConfig)


# --- fitting --------------------------------------------------------------------------


def element_responses(
    breakpoints_m: FloatArray, template: GmsParams, position_m: FloatArray, velocity_m_s: FloatArray
) -> FloatArray:
    """Force of each unit-stiffness element (W_i = Delta_i) along a path, shape (T, N)."""
    unit = _with_elements(template, np.ones(breakpoints_m.size), np.asarray(breakpoints_m))
    return simulate_elements(unit, position_m, velocity_m_s)


def _with_elements(
    template: GmsParams, k: FloatArray, w: FloatArray, slip_level: float | None = None
) -> GmsParams:
    level = template.slip_level if slip_level is None else slip_level
    return dataclasses.replace(template, stiffness_N_per_m=k, limit_N=w, slip_level=level)


def design_matrix(
    breakpoints_m: FloatArray,
    slip_level: float,
    template: GmsParams,
    curve_x_m: FloatArray,
    paths: Sequence[Reference],
) -> FloatArray:
    """Unit-stiffness element forces: rows are the virgin curve, then every path sample."""
    model = _with_elements(template, np.ones(1), np.ones(1), slip_level)
    rows = [element_shape(curve_x_m, breakpoints_m, slip_level)]
    rows += [element_responses(breakpoints_m, model, pos, vel) for (pos, vel), _ in paths]
    return np.vstack(rows)


def equal_force_breakpoints(x_m: FloatArray, force_N: FloatArray, n_elements: int) -> FloatArray:
    """Where a (virgin) curve reaches (i + 1/2) / N of its end force, i = 0 .. N-1."""
    rising = np.maximum.accumulate(force_N)
    levels = (np.arange(n_elements) + 0.5) / n_elements * rising[-1]
    return np.exp(np.interp(levels, rising, np.log(x_m)))


def fit_elements(
    n_elements: int,
    template: GmsParams,
    curve: tuple[FloatArray, FloatArray],
    paths: Sequence[Reference] = (),
    *,
    fit_slip_level: bool = True,
    max_evaluations: int = 60,
) -> tuple[GmsParams, float]:
    """N elements fitted to a virgin curve and reference paths; the model and its RMS residual.

    ``curve`` is (displacement > 0, force) of the virgin curve while moving;
    ``paths`` are ((position, velocity), force) samples of the reference. The
    slip level is fitted between 1 and ``template.slip_level`` when
    ``fit_slip_level``, else kept. See the module docstring for the method.
    """
    x, f = curve
    if not f[-1] > 0.0:
        raise ValueError(f"the curve must end at a positive force, got {f[-1]!r}")
    target = np.concatenate(
        [f] + [force - template.viscous_Ns_per_m * vel for (_, vel), force in paths]
    )
    n = n_elements
    c_v = template.slip_level
    free_level = fit_slip_level and c_v != 1.0
    bp0 = equal_force_breakpoints(x, f, n)
    k0 = f[-1] / (c_v * n) / bp0

    def unpack(p: FloatArray) -> tuple[FloatArray, FloatArray, float]:
        return np.exp(p[:n]), np.exp(p[n : 2 * n]), float(p[2 * n]) if free_level else c_v

    def residual(p: FloatArray) -> FloatArray:
        k, bp, level = unpack(p)
        return design_matrix(bp, level, template, x, paths) @ k - target

    def jacobian(p: FloatArray) -> FloatArray:
        k, bp, level = unpack(p)
        a = design_matrix(bp, level, template, x, paths)
        shifted = design_matrix(bp * np.exp(_LOG_STEP), level, template, x, paths)
        columns = [a * k, (shifted - a) / _LOG_STEP * k]
        if free_level:
            raised = design_matrix(bp, level + _LEVEL_STEP, template, x, paths)
            columns.append(((raised - a) @ k / _LEVEL_STEP)[:, None])
        return np.hstack(columns)

    spread = np.log(_STIFFNESS_RANGE)
    lower = [np.log(k0) - spread, np.full(n, np.log(x[0]))]
    upper = [np.log(k0) + spread, np.full(n, np.log(x[-1]))]
    start = [np.log(k0), np.log(bp0)]
    if free_level:
        lower.append(np.array([min(1.0, c_v)]))
        upper.append(np.array([max(1.0, c_v)]))
        start.append(np.array([c_v]))
    fit = least_squares(
        residual,
        np.clip(np.concatenate(start), np.concatenate(lower), np.concatenate(upper)),
        jac=jacobian,
        bounds=(np.concatenate(lower), np.concatenate(upper)),
        x_scale="jac",
        # Iterative steps (products with J) instead of an SVD of J per iteration: the
        # same fit, and no multithreaded LAPACK call that stalls on a busy machine.
        tr_solver="lsmr",
        max_nfev=max_evaluations,
    )
    k, bp, level = unpack(fit.x)
    order = np.argsort(bp)
    model = _with_elements(template, k[order], k[order] * bp[order], level)
    return model, float(np.sqrt(np.mean(fit.fun**2)))


# --- fidelity -------------------------------------------------------------------------


def fidelity(
    params: GmsParams, references: Iterable[Reference], sliding_force_N: float
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


def with_reference(model: ForceModel, paths: Iterable[Path_]) -> list[Reference]:
    """Each path paired with the reference model's force along it."""
    return [((x, v), model(x, v)) for x, v in paths]


# --- the ball model ---------------------------------------------------------------------


@dataclass(frozen=True)
class _BallData:
    """What the fit and the fidelity need from one ball-set config."""

    curve: tuple[FloatArray, FloatArray]
    training: list[Reference]
    test: list[Reference]
    sliding_force_N: float


def _ball_data(cfg: BallConfig, tc: TableConfig) -> _BallData:
    """Virgin curve, training path and the two test paths (Fig. 7, random) of the ball set.

    The random paths' amplitudes span 1 % to 3 x the presliding length (where
    the virgin curve reaches 99.9 % of its end).
    """
    ball = BallSetFriction(cfg)
    curve = _ball_curve(ball, tc)
    x, f = curve
    presliding_m = float(np.exp(np.interp(0.999 * f[-1], np.maximum.accumulate(f), np.log(x))))
    speed = cfg.stand.carriage_velocity_m_s
    rng = np.random.default_rng(tc.random_seed)
    amplitudes = (0.01 * presliding_m, 3.0 * presliding_m)
    training, test = (
        random_path(rng, tc.random_reversals, amplitudes, speed, tc.sample_rate_Hz)
        for _ in range(2)
    )
    _t, fig7_x, fig7_v = seed_fig7_profile(tc.sample_rate_Hz, velocity_m_s=speed)
    return _BallData(
        curve,
        with_reference(ball.force, [training]),
        with_reference(ball.force, [(fig7_x, fig7_v), test]),
        ball.sliding_force_N,
    )


def _ball_curve(ball: BallSetFriction, tc: TableConfig) -> tuple[FloatArray, FloatArray]:
    """The virgin curve, or half the reversal curve at twice the displacement (Masing)."""
    x = np.geomspace(1e-10, 1e-2, tc.curve_points)
    if tc.curve == "virgin":
        return x, ball.virgin_curve(x)
    reversal = ball.reversal_curve(np.concatenate([[0.0], 2.0 * x]))
    return x, 0.5 * (reversal[1:] - reversal[0])


def _at_ball_load(cfg: BallConfig, normal_load_N: float) -> BallConfig:
    """``cfg`` with every ball carrying ``normal_load_N``."""
    loads = (normal_load_N,) * len(cfg.stand.ball_loads_N)
    return dataclasses.replace(cfg, stand=dataclasses.replace(cfg.stand, ball_loads_N=loads))


def check_request(cfg: BallConfig, n_elements: int, tc: TableConfig) -> None:
    """Refuse an element count or family loads that bypassed the config's bounds
    (command-line values), or family loads outside the Hertz model, before any work is
    done (``gms-comp config`` calls it too)."""
    if isinstance(n_elements, bool) or not 1 <= n_elements <= MAX_TABLE_ELEMENTS:
        raise InputError(
            "elements", "", f"must be in [1, {MAX_TABLE_ELEMENTS}], got {n_elements!r}"
        )
    loads = tc.family_loads_N
    if len(loads) > MAX_FAMILY_LOADS:
        raise InputError(
            "family loads", "", f"{len(loads)} loads, more than the {MAX_FAMILY_LOADS} allowed"
        )
    for i, load in enumerate(loads):
        if not 1e-3 <= load <= 1e5:
            raise ConfigError(
                cfg.path, f"table.family_loads_N[{i}]", f"must be in [0.001, 100000], got {load!r}"
            )
    check_loads(cfg, loads, "table.family_loads_N")


def reduce_to_gms(
    cfg: BallConfig,
    n_elements: int | None = None,
    table_cfg: TableConfig | None = None,
    *,
    ball_sets: float = 1.0,
    progress: bool = False,
) -> GmsTable:
    """Reduce the configured ball set to a GMS table of exactly N elements, for
    ``ball_sets`` such sets moving together (the whole axis's friction).

    Parameters
    ----------
    cfg
        The physics config (its file is hashed into the table).
    n_elements
        N; default ``table_cfg.elements``.
    table_cfg
        Reduction settings; default: the ``[table]`` section of ``cfg.path``.
        With ``family_loads_N`` the table also holds a load family: the same N
        elements refitted with every ball at each of those loads (at the main
        fit's slip level, so only k_i and W_i vary along the family).
    ball_sets
        Identical ball sets in parallel see the same displacement: the fitted k_i, W_i
        (and the family's rows) are multiplied by this count, which the table records
        in ``scaled_by`` with the set's ball loads. Its fidelity is relative, unchanged.
    progress
        Show a progress bar on stderr.
    """
    tc = table_cfg if table_cfg is not None else load_table_config(cfg.path)
    n = n_elements if n_elements is not None else tc.elements
    check_request(cfg, n, tc)
    template = GmsParams(
        np.ones(1),
        np.ones(1),
        slip_level=cfg.bearing.slip_exaggeration,
        transition_velocity_m_s=tc.transition_velocity_m_s,
        transition_exponent=tc.transition_exponent,
    )
    loads = sorted(set(tc.family_loads_N))
    with tqdm(total=3 + len(loads), desc="gms table", disable=not progress, leave=False) as bar:
        data = _ball_data(cfg, tc)
        bar.update()
        params, _ = fit_elements(
            n,
            template,
            data.curve,
            data.training,
            fit_slip_level=tc.fit_slip_level,
            max_evaluations=tc.refinement_evaluations,
        )
        bar.update()
        quality = fidelity(params, data.test, data.sliding_force_N)
        bar.update()
        rows = []
        for load in loads:
            member = _ball_data(_at_ball_load(cfg, load), tc)
            rows.append(
                fit_elements(
                    n,
                    params,
                    member.curve,
                    member.training,
                    fit_slip_level=False,
                    max_evaluations=tc.refinement_evaluations,
                )[0]
            )
            bar.update()
    family = (
        LoadFamily(
            np.array(loads),
            np.array([p.stiffness_N_per_m for p in rows]) * ball_sets,
            np.array([p.limit_N for p in rows]) * ball_sets,
        )
        if loads
        else None
    )
    return GmsTable(
        params=scaled(params, ball_sets, 1.0, viscous_Ns_per_m=params.viscous_Ns_per_m * ball_sets),
        source_config=str(cfg.path),
        source_sha256=config_hash(cfg.path),
        fidelity=quality,
        load_family=family,
        scaled_by=Scaling(float(ball_sets), tuple(cfg.stand.ball_loads_N)),
    )
