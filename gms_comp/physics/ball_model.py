"""The seed's stripe/bristle model of the ball/raceway contact in steady rolling.

The contact ellipse is cut into stripes across the motion (transverse position
y). A bristle enters a stripe with zero displacement at the leading edge and
accumulates the local slip xi(y) per unit rolling distance (seed Eqs. 7-10),
so in steady rolling u(x, y) = xi(y) (x + a(y)) with x = -a(y) at entry. Its
traction is k_q u until |k_q u| reaches f_max(y) = mu p(0, y) (Eqs. 1, 4, 6);
then the bristle slips and carries C_v f_max(y).

The lines of pure rolling y = +-b0 minimise the frictional moment of Eq. (14),
counted as resisting (every |F| h >= 0) over the four areas
[0, b-], [b-, b0], [b0, b+], [b+, b]; b-/b+ bound the stripes that stick
across their whole length (Eq. 12). docs/model.md derives every step.
"""

from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from gms_comp.arrays import FloatArray
from gms_comp.errors import ConfigError
from gms_comp.physics.config import BallConfig, ModelConfig
from gms_comp.physics.contact import (
    HertzContact,
    contact_problem,
    effective_shear_modulus_Pa,
    hertz_contact,
)

#: The seed's Eq. (2) modulus E' (N/mm^2) is used as k_q in N/mm^3: per millimetre.
SEED_STIFFNESS_LENGTH_m = 1e-3


def tangential_stiffness_N_per_m3(cfg: BallConfig, contact: HertzContact) -> float:
    """Bristle stiffness k_q (traction per displacement) in the configured reading.

    ``"seed"``: k_q = E' / (1 mm) with E' = 2 E* (seed Eq. 2 taken numerically per
    mm, which is how the paper's numbers come out). ``"mindlin"``: Mindlin's
    initial tangential stiffness 8 G* c of a contact of equivalent radius
    c = sqrt(a b), spread uniformly over the contact area pi a b.
    """
    if cfg.model.tangential_stiffness == "seed":
        return 2.0 * contact.e_star_Pa / SEED_STIFFNESS_LENGTH_m
    c = math.sqrt(contact.a_m * contact.b_m)
    g_star = effective_shear_modulus_Pa(cfg.bearing)
    return 8.0 * g_star * c / (math.pi * contact.a_m * contact.b_m)


@dataclass(frozen=True)
class StripeModel:
    """Bristle field parameters of one contact; every method works on arrays of y."""

    contact: HertzContact
    ball_radius_m: float
    friction_coefficient: float
    slip_exaggeration: float
    k_q_N_per_m3: float

    def traction_limit_Pa(self, y_m: FloatArray) -> FloatArray:
        """f_max(y) = mu p(0, y) (seed Eq. 4)."""
        return self.friction_coefficient * self.contact.pressure_Pa(0.0, y_m)

    def slip_limit_m(self, y_m: FloatArray) -> FloatArray:
        """u_max(y) = f_max(y) / k_q (seed Eq. 6)."""
        return self.traction_limit_Pa(y_m) / self.k_q_N_per_m3

    def slip_ratio(self, y_m: FloatArray, xi0: float) -> FloatArray:
        """xi(y) = xi0 + (1 - xi0) y^2 / (2 R^2): slip per unit rolling distance (Eq. 8)."""
        return xi0 + (1.0 - xi0) * y_m**2 / (2.0 * self.ball_radius_m**2)

    def full_stick_slip_ratio(self) -> float:
        """|xi| below which a stripe sticks over its whole length: 3 Q mu / (4 pi a^2 b k_q).

        From a0(y) = a(y) in Eq. (11): u_max(y) / (2 a(y)) is the same for every
        stripe, mu p0 / (2 a k_q) (seed Eq. 12).
        """
        c = self.contact
        return (
            3.0
            * c.normal_load_N
            * self.friction_coefficient
            / (4.0 * math.pi * c.a_m**2 * c.b_m * self.k_q_N_per_m3)
        )

    def stick_length_m(self, y_m: FloatArray, xi0: float) -> FloatArray:
        """Length a0(y) + a(y) of the stick zone behind the leading edge (Eq. 11)."""
        full = 2.0 * self.contact.half_length_m(y_m)
        xi = np.abs(self.slip_ratio(y_m, xi0))
        with np.errstate(divide="ignore"):
            reach = np.where(xi > 0.0, self.slip_limit_m(y_m) / xi, np.inf)
        return np.minimum(full, reach)

    def stripe_force_N_per_m(self, y_m: FloatArray, xi0: float) -> FloatArray:
        """Signed steady stripe force f(y) = int F dx (seed Eq. 17), sign of xi(y).

        Stick zone: int_0^L k_q |xi| s ds = k_q |xi| L^2 / 2; slip zone: C_v f_max (2a - L).
        """
        xi = self.slip_ratio(y_m, xi0)
        length = self.stick_length_m(y_m, xi0)
        full = 2.0 * self.contact.half_length_m(y_m)
        stick = 0.5 * self.k_q_N_per_m3 * np.abs(xi) * length**2
        slip = self.slip_exaggeration * self.traction_limit_Pa(y_m) * (full - length)
        return np.sign(xi) * (stick + slip)

    def area_bounds_m(self, beta: float) -> tuple[float, float, float, float, float]:
        """(0, b-, b0, b+, b): the y limits of the four areas of Eq. (14)."""
        b = self.contact.b_m
        b0 = beta * b
        xi0 = xi0_from_beta(beta, b, self.ball_radius_m)
        c = self.full_stick_slip_ratio()
        scale = 2.0 * self.ball_radius_m**2 / (1.0 - xi0)
        b_minus = math.sqrt(max(-xi0 - c, 0.0) * scale)
        b_plus = min(math.sqrt((-xi0 + c) * scale), b)
        return 0.0, min(b_minus, b0), b0, max(b_plus, b0), b


def xi0_from_beta(beta: float, b_m: float, ball_radius_m: float) -> float:
    """xi0 = -b0^2 / (2 R^2 - b0^2), from xi(b0) = 0 (seed Eq. 16)."""
    b0 = beta * b_m
    return -(b0**2) / (2.0 * ball_radius_m**2 - b0**2)


def area_nodes(bounds: tuple[float, ...], nodes_per_area: int) -> tuple[FloatArray, FloatArray]:
    """Gauss-Legendre nodes and weights on each area between consecutive ``bounds``.

    The kinks of the integrands sit at b-, b0, b+, so each area is smooth
    inside. The last area ends at the ellipse edge y = b, where a(y) has a
    square-root end point; there y = b - (b - lo) s^2 makes the integrand
    smooth in s.
    """
    t, w = np.polynomial.legendre.leggauss(nodes_per_area)
    ys, ws = [], []
    pairs = list(itertools.pairwise(bounds))
    for lo, hi in pairs[:-1]:
        half = 0.5 * (hi - lo)
        ys.append(lo + half * (t + 1.0))
        ws.append(half * w)
    lo, hi = pairs[-1]
    s = 0.5 * (t + 1.0)
    ys.append(hi - (hi - lo) * s**2)
    ws.append((hi - lo) * s * w)  # |dy/ds| ds = 2 (hi - lo) s * (w / 2)
    return np.concatenate(ys), np.concatenate(ws)


def levers_m(y_m: FloatArray, b0_m: float, rho_m: float) -> FloatArray:
    """|h_I|, |h_II| of Eq. (13): |sqrt(rho^2 - y^2) - sqrt(rho^2 - b0^2)|.

    Written as |b0^2 - y^2| / (sqrt(rho^2 - y^2) + sqrt(rho^2 - b0^2)) to stay
    exact for large rho.
    """
    return np.abs(b0_m**2 - y_m**2) / (np.sqrt(rho_m**2 - y_m**2) + np.sqrt(rho_m**2 - b0_m**2))


def friction_torque_Nm(model: StripeModel, beta: float, lam: float, nodes_per_area: int) -> float:
    """M(beta, lambda) of Eq. (14), every contribution counted as resisting."""
    b = model.contact.b_m
    y, w = area_nodes(model.area_bounds_m(beta), nodes_per_area)
    xi0 = xi0_from_beta(beta, b, model.ball_radius_m)
    force = np.abs(model.stripe_force_N_per_m(y, xi0))
    return float(2.0 * np.sum(w * force * levers_m(y, beta * b, lam * b)))


def best_beta(model: StripeModel, lam: float, nodes_per_area: int) -> float:
    """The beta in (0, 1) that minimises M(beta, lambda) for one lambda."""
    result = minimize_scalar(
        lambda beta: friction_torque_Nm(model, float(beta), lam, nodes_per_area),
        bounds=(1e-3, 1.0 - 1e-3),
        method="bounded",
        options={"xatol": 1e-8},
    )
    return float(result.x)


def sliding_force_of(model: StripeModel, beta: float, nodes_per_area: int) -> float:
    """Steady sliding force of one contact: the resisting sum of |f(y)| over the ellipse."""
    y, w = area_nodes(model.area_bounds_m(beta), nodes_per_area)
    xi0 = xi0_from_beta(beta, model.contact.b_m, model.ball_radius_m)
    return float(2.0 * np.sum(w * np.abs(model.stripe_force_N_per_m(y, xi0))))


@dataclass(frozen=True)
class SteadyResult:
    """Steady rolling of one ball: rolling lines, slip and sliding force (SI)."""

    contact: HertzContact
    k_q_N_per_m3: float
    beta: float  # b0 / b at the physical lambda
    lam: float  # rho / b with rho = R (see docs/model.md)
    xi0: float
    b0_m: float
    b_minus_m: float
    b_plus_m: float
    sliding_force_N: float
    lambdas: tuple[float, ...]  # the search grid of Eq. (15)
    betas: tuple[float, ...]  # the minimising beta for each lambda


def stripe_model(cfg: BallConfig, normal_load_N: float) -> StripeModel:
    """The bristle-field parameters of one ball under ``normal_load_N``.

    Raises
    ------
    ConfigError
        When the load makes a contact outside the Hertz model (see
        :func:`gms_comp.physics.contact.contact_problem`), naming the config file.
    """
    contact = hertz_contact(cfg.bearing, normal_load_N)
    problem = contact_problem(contact, cfg.bearing.ball_radius_m)
    if problem is not None:
        raise ConfigError(cfg.path, "stand.ball_loads_N", problem)
    return StripeModel(
        contact=contact,
        ball_radius_m=cfg.bearing.ball_radius_m,
        friction_coefficient=cfg.bearing.friction_coefficient,
        slip_exaggeration=cfg.bearing.slip_exaggeration,
        k_q_N_per_m3=tangential_stiffness_N_per_m3(cfg, contact),
    )


def lambda_grid(model_cfg: ModelConfig) -> FloatArray:
    """Log-spaced lambda values of the rolling-line search."""
    return np.geomspace(model_cfg.lambda_min, model_cfg.lambda_max, model_cfg.lambda_count)


def rolling_lines(model: StripeModel, lam: float, nodes_per_area: int) -> tuple[float, float]:
    """(beta, xi0) of the rolling lines for one lambda."""
    beta = best_beta(model, lam, nodes_per_area)
    return beta, xi0_from_beta(beta, model.contact.b_m, model.ball_radius_m)


@functools.lru_cache(maxsize=64)
def steady_state(cfg: BallConfig, normal_load_N: float) -> SteadyResult:
    """Search the rolling lines over beta and lambda (Eq. 15) and the sliding force.

    For each lambda of the configured grid the minimising beta is found; the
    reported rolling line is the one at rho = R (lambda = R / b), where M times
    the ball's angular velocity is the power dissipated by slip. Results are
    cached per (config, load): balls of equal load share one search.
    """
    model = stripe_model(cfg, normal_load_N)
    n = cfg.model.steady_nodes_per_area
    lambdas = lambda_grid(cfg.model)
    betas = [best_beta(model, float(lam), n) for lam in lambdas]
    lam = cfg.bearing.ball_radius_m / model.contact.b_m
    beta, xi0 = rolling_lines(model, lam, n)
    _, b_minus, b0, b_plus, _ = model.area_bounds_m(beta)
    return SteadyResult(
        contact=model.contact,
        k_q_N_per_m3=model.k_q_N_per_m3,
        beta=beta,
        lam=lam,
        xi0=xi0,
        b0_m=b0,
        b_minus_m=b_minus,
        b_plus_m=b_plus,
        sliding_force_N=sliding_force_of(model, beta, n),
        lambdas=tuple(float(v) for v in lambdas),
        betas=tuple(betas),
    )


def sliding_force_N(cfg: BallConfig) -> float:
    """Steady sliding friction of the configured ball set (sum over the balls)."""
    return sum(steady_state(cfg, load).sliding_force_N for load in cfg.stand.ball_loads_N)
