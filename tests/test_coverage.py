"""What a trace's motion cannot tell apart: the speed/direction confound.

Velocity profiles are built by hand here (plateaus joined by linear ramps), so the
expected answer follows from the profile, not from the code under test."""

from __future__ import annotations

import numpy as np
import pytest

from gms_comp.measured.diagnosis.coverage import (
    SPEED_OR_DIRECTION,
    caveats,
    speed_bands,
    speed_direction_confound,
)

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
    caveat = speed_direction_confound(v, STILL)
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
    assert speed_direction_confound(profile(*moves), STILL) is None


def test_ramps_between_plateaus_are_not_bands() -> None:
    # 40-sample ramps against 4000-sample plateaus: under 2 % of the time in any bin
    bands = speed_bands(np.abs(profile((5e-3, 4000)))[np.abs(profile((5e-3, 4000))) > STILL])
    assert len(bands) == 1
    lo, hi, share = bands[0]
    assert lo <= 5e-3 <= hi and share > 0.95


def test_a_caveat_is_given_only_where_it_concerns_an_effect_named() -> None:
    v = profile((6.9e-3, 4000), (-1.2e-3, 14000))
    assert [c.kind for c in caveats(v, STILL, ["direction_asymmetry"])] == ["speed_direction"]
    assert [c.kind for c in caveats(v, STILL, ["stribeck", "dwell_time"])] == ["speed_direction"]
    assert caveats(v, STILL, ["dwell_time"]) == ()
    assert caveats(v, STILL, []) == ()
    assert set(SPEED_OR_DIRECTION) >= {"stribeck", "direction_asymmetry"}
