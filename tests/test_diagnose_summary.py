"""The diagnosis summary for people: the extended model's level, its approach to C_v and
the caveats, from a hand-written JSON (the keys `gms-comp diagnose --json` writes)."""

from __future__ import annotations

from typing import Any

import pytest

from gms_comp.app.commands.diagnose import summary


def _doc(**extended: Any) -> dict[str, Any]:
    baseline = {
        "model": "free_nnls_gms", "sliding_force_N": 34.7, "slip_level": 1.065,
        "limit_follows_level": False, "transition_tail": None,
    }  # fmt: skip
    return {
        "trace": "stribeck-251.csv", "seconds": 5.4, "baseline": baseline,
        "baseline_rms_N": 2.935, "noise_rms_N": 0.6225, "extended_rms_N": 0.6847,
        "gain": 0.767, "phases": {}, "effect": "stribeck",
        "effects": [{"effect": "stribeck", "parameters": {"ratio": 1.337,
                                                          "v_s_m_per_s": 3.179e-3}}],
        "structure": {"description": ""},
        "caveats": [{"kind": "at_bound", "effects": ["stribeck"],
                     "text": "stribeck's v_s_m_per_s at its upper bound 0.003179: ..."}],
    } | extended  # fmt: skip


def _level_line(text: str) -> str | None:
    return next((line for line in text.splitlines() if "with the slip level" in line), None)


def test_a_level_reached_on_the_rational_approach_is_said() -> None:
    text = summary(_doc(extended_slip_level=1.35, extended_transition_tail=1.0), 109692, "friction")
    line = _level_line(text)
    assert line is not None
    assert "C_v 1.35" in line and "rational (tail 1)" in line and "GMS alone: 1.06" in line
    assert "caveat: stribeck's v_s_m_per_s at its upper bound" in text


@pytest.mark.parametrize(
    ("extended", "said"),
    [
        ({"extended_slip_level": 1.065, "extended_transition_tail": None}, False),
        ({"extended_slip_level": 1.30, "extended_transition_tail": None}, True),
        ({"extended_slip_level": 1.065, "extended_transition_tail": 1.0}, True),
        ({}, False),  # a JSON written before the extended tail was reported
    ],
    ids=["unchanged", "level-moved", "tail-only", "older-json"],
)
def test_the_level_line_appears_only_where_the_level_or_its_approach_moved(
    extended: dict[str, Any], said: bool
) -> None:
    line = _level_line(summary(_doc(**extended), 109692, "friction"))
    assert (line is not None) == said
    if line is not None:
        assert ("rational" in line) == (extended.get("extended_transition_tail") is not None)
