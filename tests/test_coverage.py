"""What a trace's motion cannot tell apart: the speed/direction confound, and the fit's
near ties.

Velocity profiles are built by hand here (plateaus joined by linear ramps), so the
expected answer follows from the profile, not from the code under test."""

from __future__ import annotations

import numpy as np
import pytest

from gms_comp.measured.diagnosis.config import CaveatConfig
from gms_comp.measured.diagnosis.coverage import (
    SPEED_OR_DIRECTION,
    at_bound,
    caveats,
    near_tie,
    speed_bands,
    speed_direction_confound,
)
from gms_comp.runtime import effects as fx

RULES = CaveatConfig()

STILL = 1e-5  # m/s


def profile(*moves: tuple[float, int]) -> np.ndarray:
    """Velocity samples (m/s): for each (speed, samples) a ramp up of 40 samples, the
    plateau, a ramp down and 200 samples at rest."""
    parts = []
    for speed, samples in moves:
        ramp = np.linspace(0.0, speed, 40)
        parts += [ramp, np.full(samples, speed), ramp[::-1], np.zeros(200)]
    return np.concatenate(parts)


def test_one_speed_each_way_is_a_confound_and_names_both_speeds() -> None:
    # seed 119 of the independent generator: 6.9 mm/s forward, 1.2 mm/s back
    v = profile((6.9e-3, 4000), (-1.2e-3, 14000), (6.9e-3, 4000))
    caveat = speed_direction_confound(v, STILL, RULES)
    assert caveat is not None
    assert caveat.kind == "speed_direction"
    assert {"stribeck", "direction_asymmetry", "viscous", "offset"} <= set(caveat.effects)
    # the bands hold the plateaus: 6.9 within the forward one, 1.2 within the back one
    numbers = [float(s) for s in caveat.text.replace("-", " ").split() if s[0].isdigit()]
    f_lo, f_hi, b_lo, b_hi = numbers[:4]
    assert f_lo <= 6.9 <= f_hi and f_hi / f_lo <= 2.0
    assert b_lo <= 1.2 <= b_hi and b_hi / b_lo <= 2.0


@pytest.mark.parametrize(
    "moves",
    [
        # the same speed both ways: the direction is told from the speed
        ((3e-3, 5000), (-3e-3, 5000)),
        # two speeds forward: a fall with speed is seen within one direction
        ((2e-3, 5000), (8e-3, 3000), (-1.2e-3, 6000)),
        # a sweep of speeds back (wider than a factor 2)
        ((6.9e-3, 5000), *((-s, 800) for s in np.geomspace(0.5e-3, 5e-3, 8))),
        # one direction only: no direction to confound
        ((5e-3, 5000), (2e-3, 5000)),
    ],
    ids=["same-speed", "two-speeds-forward", "sweep-back", "one-way"],
)
def test_no_confound_where_the_motion_tells_speed_from_direction(
    moves: tuple[tuple[float, int], ...],
) -> None:
    assert speed_direction_confound(profile(*moves), STILL, RULES) is None


def test_ramps_between_plateaus_are_not_bands() -> None:
    # 40-sample ramps against 4000-sample plateaus: under 2 % of the time in any bin
    bands = speed_bands(
        np.abs(profile((5e-3, 4000)))[np.abs(profile((5e-3, 4000))) > STILL], RULES.band_share
    )
    assert len(bands) == 1
    lo, hi, share = bands[0]
    assert lo <= 5e-3 <= hi and share > 0.95


def test_a_caveat_is_given_only_where_it_concerns_an_effect_named() -> None:
    v = profile((6.9e-3, 4000), (-1.2e-3, 14000))
    assert [c.kind for c in caveats(v, STILL, ["direction_asymmetry"], RULES)] == [
        "speed_direction"
    ]
    assert [c.kind for c in caveats(v, STILL, ["stribeck", "dwell_time"], RULES)] == [
        "speed_direction"
    ]
    assert caveats(v, STILL, ["dwell_time"], RULES) == ()
    assert caveats(v, STILL, [], RULES) == ()
    assert set(SPEED_OR_DIRECTION) >= {"stribeck", "direction_asymmetry"}


def test_a_mass_in_a_force_read_as_friction_is_said_to_be_perhaps_a_drive_force() -> None:
    v = profile((6.9e-3, 4000), (-6.9e-3, 4000))
    assert [c.kind for c in caveats(v, STILL, ["inertia"], RULES)] == ["drive_force"]
    assert "--force-kind drive" in caveats(v, STILL, ["inertia", "offset"], RULES)[0].text
    assert caveats(v, STILL, ["inertia"], RULES, force_kind="drive") == ()
    assert caveats(v, STILL, ["offset", "inertia"], RULES) == ()  # only a mass named first


def test_a_rival_that_took_most_of_the_first_effect_s_drop_is_a_near_tie() -> None:
    # independent stribeck-223: drift and stribeck both took 0.1704 N to 0.1551 N
    caveat = near_tie("drift", 0.1704, [("drift", 0.1551), ("stribeck", 0.1551)], RULES.near_tie)
    assert caveat is not None
    assert caveat.kind == "near_tie"
    assert caveat.effects == ("drift", "stribeck")
    assert "0.1704" in caveat.text and caveat.text.count("0.1551") == 2
    # drops of 1.0 N (first) against near_tie of it, just above and just below
    above = 10.0 - RULES.near_tie * 1.0 * 1.001
    below = 10.0 - RULES.near_tie * 1.0 * 0.999
    near = near_tie(
        "offset", 10.0, [("offset", 9.0), ("viscous", above), ("drift", below)], RULES.near_tie
    )
    assert near is not None and near.effects == ("offset", "viscous")


@pytest.mark.parametrize(
    "first, trials",
    [
        ("offset", [("offset", 9.0)]),  # alone
        ("offset", [("offset", 9.0), ("viscous", 9.5)]),  # half the drop
        ("inertia", [("offset", 9.0), ("viscous", 9.0)]),  # the refit ranked another first
        ("offset", [("offset", 10.0), ("viscous", 10.0)]),  # no drop to share
        ("offset", []),  # no round recorded
    ],
)
def test_no_near_tie_without_a_rival_close_to_the_first_effect(
    first: str, trials: list[tuple[str, float]]
) -> None:
    assert near_tie(first, 10.0, trials, RULES.near_tie) is None


def test_a_near_tie_is_a_caveat_only_about_the_first_effect_named() -> None:
    v = profile((5e-3, 4000), (-5e-3, 4000))  # no speed/direction confound
    round1 = (0.1704, [("drift", 0.1551), ("stribeck", 0.1551)])
    assert [c.kind for c in caveats(v, STILL, ["drift", "offset"], RULES, round1)] == ["near_tie"]
    assert caveats(v, STILL, ["offset", "drift"], RULES, round1) == ()
    assert caveats(v, STILL, [], RULES, round1) == ()


def _context(v: np.ndarray, rate_Hz: float = 2000.0) -> fx.Context:
    t = np.arange(v.size) / rate_Hz
    x = np.cumsum(v) / rate_Hz
    return fx.Context.along(t, x, v, np.gradient(v, t), 0 * t)


def test_a_stribeck_speed_at_half_the_top_speed_is_at_its_bound() -> None:
    # stribeck-251 of the independent generator: top speed 6.35 mm/s, the true fall's
    # v_s 5.67 mm/s; the search stops at half the top speed
    ctx = _context(profile((6.35e-3, 4000), (-1.07e-3, 20000)))
    caveat = at_bound([fx.Stribeck(1.34, 0.5 * 6.35e-3)], ctx, 50e-6, RULES.at_bound)
    assert caveat is not None
    assert caveat.kind == "at_bound" and caveat.effects == ("stribeck",)
    assert "v_s_m_per_s at its upper bound" in caveat.text
    # ... and only the effect at a bound is named
    both = at_bound(
        [fx.Viscous(10.0), fx.Stribeck(1.34, 0.5 * 6.35e-3)], ctx, 50e-6, RULES.at_bound
    )
    assert both is not None and both.effects == ("stribeck",)


@pytest.mark.parametrize("v_s", [0.3e-3, 1.0e-3, 3.0e-3], ids=["slow", "mid", "just-inside"])
def test_a_stribeck_speed_inside_its_range_is_no_caveat(v_s: float) -> None:
    ctx = _context(profile((6.35e-3, 4000), (-1.07e-3, 20000)))
    assert at_bound([fx.Stribeck(1.34, v_s)], ctx, 50e-6, RULES.at_bound) is None


def test_an_at_bound_caveat_is_listed_with_the_others_when_its_effect_is_named() -> None:
    ctx = _context(profile((6.35e-3, 4000), (-1.07e-3, 20000)))
    bounded = at_bound([fx.Stribeck(1.34, 0.5 * 6.35e-3)], ctx, 50e-6, RULES.at_bound)
    listed = caveats(ctx.velocity_m_s, STILL, ["stribeck"], RULES, bounded=bounded)
    # one speed each way: the speed/direction confound as well
    assert [c.kind for c in listed] == ["speed_direction", "at_bound"]
    assert (
        caveats(ctx.velocity_m_s, STILL, ["viscous"], RULES, bounded=bounded)[-1].kind != "at_bound"
    )
