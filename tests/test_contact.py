"""Exact Hertz contact of the ball in the groove against the spec's reference values."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate

from gms_comp.physics.config import BearingConfig, load_ball_config
from gms_comp.physics.contact import hertz_contact


@pytest.fixture(scope="module")
def bearing() -> BearingConfig:
    return load_ball_config().bearing


# Reference values of physics.md, computed independently from the potential integrals.
@pytest.mark.parametrize(
    ("attr", "expected"),
    [
        ("a_m", 65.157e-6),
        ("b_m", 307.177e-6),
        ("p0_Pa", 1192.8e6),
        ("approach_m", 2.0484e-6),
        ("e_star_Pa", 112277.5e6),
        ("ry_m", 34.192e-3),
    ],
)
def test_table1_reference_values(bearing: BearingConfig, attr: str, expected: float) -> None:
    contact = hertz_contact(bearing, 50.0)
    assert getattr(contact, attr) == pytest.approx(expected, rel=1e-3)


def test_axis_ratio(bearing: BearingConfig) -> None:
    contact = hertz_contact(bearing, 50.0)
    assert contact.b_m / contact.a_m == pytest.approx(4.7144, rel=1e-3)


def test_pressure_integrates_to_load(bearing: BearingConfig) -> None:
    contact = hertz_contact(bearing, 50.0)
    total, _ = integrate.dblquad(
        lambda x, y: float(contact.pressure_Pa(x, y)),
        -contact.b_m,
        contact.b_m,
        lambda y: -float(contact.half_length_m(y)),
        lambda y: float(contact.half_length_m(y)),
        epsabs=1e-9,
    )
    assert total == pytest.approx(50.0, rel=1e-6)


def test_conforming_limit_approaches_circle(bearing: BearingConfig) -> None:
    # A very wide groove leaves a ball on a near-flat: the contact becomes the
    # circular Hertz contact of radius (3 Q R / (4 E*))^(1/3).
    flat = dataclasses.replace(bearing, raceway_radius_m=1e6)
    contact = hertz_contact(flat, 50.0)
    radius = (3 * 50.0 * flat.ball_radius_m / (4 * contact.e_star_Pa)) ** (1 / 3)
    assert contact.a_m == pytest.approx(radius, rel=1e-4)
    assert contact.b_m == pytest.approx(radius, rel=1e-4)
    assert contact.approach_m == pytest.approx(radius**2 / flat.ball_radius_m, rel=1e-4)


@settings(max_examples=25, deadline=None)
@given(load=st.floats(1.0, 2000.0), scale=st.floats(1.5, 8.0))
def test_load_scaling(load: float, scale: float) -> None:
    # Hertz: semi-axes grow as Q^(1/3), pressure as Q^(1/3), approach as Q^(2/3).
    bearing = load_ball_config().bearing
    c1 = hertz_contact(bearing, load)
    c2 = hertz_contact(bearing, load * scale)
    s3 = scale ** (1 / 3)
    np.testing.assert_allclose(
        [c2.a_m / c1.a_m, c2.b_m / c1.b_m, c2.p0_Pa / c1.p0_Pa, c2.approach_m / c1.approach_m],
        [s3, s3, s3, s3**2],
        rtol=1e-9,
    )
    assert math.isclose(c2.b_m / c2.a_m, c1.b_m / c1.a_m, rel_tol=1e-9)


def test_rejects_non_positive_load(bearing: BearingConfig) -> None:
    with pytest.raises(ValueError, match="load"):
        hertz_contact(bearing, 0.0)
