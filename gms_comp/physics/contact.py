"""Exact Hertz contact of a ball in a straight groove (seed section 2, Table 1).

The ball (radius R) rolls along a straight raceway whose groove radius Rr > R
conforms transversely. The principal radii of the relative curvature are
``Rx = R`` along the motion and ``Ry = 1 / (1/R - 1/Rr)`` across it, so the
contact ellipse is short along the motion (semi-axis ``a``) and long across it
(semi-axis ``b``), as in the seed.

The solution is the exact one of the half-space theory (Johnson, *Contact
Mechanics*, section 4.2), with complete elliptic integrals K(e), E(e) of the
eccentricity e = sqrt(1 - a^2/b^2). scipy's ``ellipk``/``ellipe`` take the
parameter m = e^2. E* is the usual effective modulus,
1/E* = (1 - v1^2)/E1 + (1 - v2^2)/E2; the seed's Eq. (2) is E' = 2 E*.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq
from scipy.special import ellipe, ellipk


class BearingConfig(Protocol):
    """What the contact reads of a ``[bearing]`` section
    (:class:`gms_comp.physics.config.BearingConfig`, which reads its loads through
    :func:`contact_problem`, so the contact cannot import it)."""

    @property
    def ball_radius_m(self) -> float: ...  # noqa: D102
    @property
    def raceway_radius_m(self) -> float: ...  # noqa: D102
    @property
    def youngs_modulus_ball_Pa(self) -> float: ...  # noqa: D102
    @property
    def youngs_modulus_raceway_Pa(self) -> float: ...  # noqa: D102
    @property
    def poisson_ratio_ball(self) -> float: ...  # noqa: D102
    @property
    def poisson_ratio_raceway(self) -> float: ...  # noqa: D102


#: Largest contact semi-axis over the ball radius the model accepts. Hertz's half-space
#: theory needs a contact small against the bodies; beyond half the ball radius the
#: "ellipse" would wrap around the ball and every result built on it is meaningless.
MAX_SEMI_AXIS_OVER_RADIUS = 0.5


@dataclass(frozen=True)
class HertzContact:
    """Hertz solution for one ball/raceway contact; SI units."""

    normal_load_N: float
    a_m: float  # semi-axis along the motion (minor)
    b_m: float  # semi-axis across the motion (major)
    p0_Pa: float  # peak pressure
    approach_m: float  # normal approach of distant points of ball and raceway
    e_star_Pa: float  # 1/E* = (1-v1^2)/E1 + (1-v2^2)/E2
    rx_m: float  # principal radius of relative curvature along the motion
    ry_m: float  # principal radius of relative curvature across the motion

    def half_length_m(self, y_m: ArrayLike) -> NDArray[np.float64]:
        """Half length a(y) of the stripe at transverse position y (seed Eq. 5)."""
        y = np.asarray(y_m, dtype=float)
        return (self.a_m / self.b_m) * np.sqrt(np.clip(self.b_m**2 - y**2, 0.0, None))

    def pressure_Pa(self, x_m: ArrayLike, y_m: ArrayLike) -> NDArray[np.float64]:
        """Hertz pressure p(x, y), zero outside the ellipse (seed Eq. 3)."""
        x = np.asarray(x_m, dtype=float)
        y = np.asarray(y_m, dtype=float)
        r2 = 1.0 - (x / self.a_m) ** 2 - (y / self.b_m) ** 2
        return self.p0_Pa * np.sqrt(np.clip(r2, 0.0, None))


def effective_modulus_Pa(bearing: BearingConfig) -> float:
    """E* with 1/E* = (1 - v1^2)/E1 + (1 - v2^2)/E2 (half the seed's E' of Eq. 2)."""
    compliance = (1.0 - bearing.poisson_ratio_ball**2) / bearing.youngs_modulus_ball_Pa + (
        1.0 - bearing.poisson_ratio_raceway**2
    ) / bearing.youngs_modulus_raceway_Pa
    return 1.0 / compliance


def effective_shear_modulus_Pa(bearing: BearingConfig) -> float:
    """G* with 1/G* = (2 - v1)/G1 + (2 - v2)/G2 (Mindlin's tangential contact)."""

    def g(e_Pa: float, nu: float) -> float:
        return e_Pa / (2.0 * (1.0 + nu))

    compliance = (2.0 - bearing.poisson_ratio_ball) / g(
        bearing.youngs_modulus_ball_Pa, bearing.poisson_ratio_ball
    ) + (2.0 - bearing.poisson_ratio_raceway) / g(
        bearing.youngs_modulus_raceway_Pa, bearing.poisson_ratio_raceway
    )
    return 1.0 / compliance


def principal_radii_m(bearing: BearingConfig) -> tuple[float, float]:
    """(Rx, Ry): relative radii of curvature along and across the motion."""
    r = bearing.ball_radius_m
    ry = 1.0 / (1.0 / r - 1.0 / bearing.raceway_radius_m)
    return r, ry


def _eccentricity_squared(radius_ratio: float) -> float:
    """e^2 of the ellipse for Ry/Rx = ``radius_ratio`` > 1.

    With the major axis across the motion, the exact theory gives
    Ry/Rx = ((b/a)^2 E - K) / (K - E); the right side grows monotonically
    from 1 (circle) to infinity as e -> 1, so the root is bracketed.
    """

    def residual(m: float) -> float:
        k, e = float(ellipk(m)), float(ellipe(m))
        return ((e / (1.0 - m) - k) / (k - e)) - radius_ratio

    if radius_ratio <= 1.0 + 1e-12:
        return 0.0
    return float(brentq(residual, 1e-12, 1.0 - 1e-15, xtol=1e-15, rtol=1e-14, maxiter=200))


def hertz_contact(bearing: BearingConfig, normal_load_N: float) -> HertzContact:
    """Solve the exact Hertz problem of one ball in the groove under ``normal_load_N``.

    Johnson's relations with the major semi-axis b across the motion:
    1/(2 Ry) = p0 a (K - E) / (E* b^2 e^2), P = (2/3) pi a b p0 and
    approach = p0 a K / E*; hence b^3 = 3 P Ry (K - E) / (pi E* e^2).
    """
    if not normal_load_N > 0.0:
        raise ValueError(f"normal load must be > 0, got {normal_load_N!r}")
    rx, ry = principal_radii_m(bearing)
    e_star = effective_modulus_Pa(bearing)
    m = _eccentricity_squared(ry / rx)
    k, e = float(ellipk(m)), float(ellipe(m))
    if m == 0.0:  # circle: K - E -> pi m / 4
        b = (3.0 * normal_load_N * rx / (4.0 * e_star)) ** (1.0 / 3.0)
    else:
        b = (3.0 * normal_load_N * ry * (k - e) / (math.pi * e_star * m)) ** (1.0 / 3.0)
    a = b * math.sqrt(1.0 - m)
    p0 = 3.0 * normal_load_N / (2.0 * math.pi * a * b)
    approach = p0 * a * k / e_star
    return HertzContact(
        normal_load_N=float(normal_load_N),
        a_m=a,
        b_m=b,
        p0_Pa=p0,
        approach_m=approach,
        e_star_Pa=e_star,
        rx_m=rx,
        ry_m=ry,
    )


def contact_problem(contact: HertzContact, ball_radius_m: float) -> str | None:
    """Why ``contact`` lies outside the Hertz model's validity, or None when it is fine.

    The semi-axes must be finite, positive and at most
    :data:`MAX_SEMI_AXIS_OVER_RADIUS` of the ball radius.
    """
    sizes = (contact.a_m, contact.b_m, contact.p0_Pa, contact.approach_m)
    if not all(math.isfinite(v) and v > 0.0 for v in sizes):
        return (
            f"a load of {contact.normal_load_N:g} N gives no finite Hertz contact "
            f"(a = {contact.a_m:g} m, b = {contact.b_m:g} m)"
        )
    limit = MAX_SEMI_AXIS_OVER_RADIUS * ball_radius_m
    if max(contact.a_m, contact.b_m) > limit:
        return (
            f"a load of {contact.normal_load_N:g} N makes a contact ellipse "
            f"{2e3 * contact.b_m:.3g} mm wide on a {2e3 * ball_radius_m:.3g} mm ball "
            f"(semi-axis > {MAX_SEMI_AXIS_OVER_RADIUS:g} x ball radius): outside the Hertz "
            "model; lower the load or check the radii and moduli"
        )
    return None
