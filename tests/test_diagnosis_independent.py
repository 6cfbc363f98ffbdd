"""Blind tests of ``gms-comp diagnose`` on traces from an independent generator.

The diagnosis is a black box here: traces come from ``indepgen`` (no code shared with the
diagnosis or with the project's own generator), go through the CLI as canonical CSV, and the
answer is judged against the generator's truth. One fixed seed per case by default;
``GMS_INDEP_SEEDS=5`` runs five (seeds 101, 102, ...). Each trace is diagnosed once per
session and shared by the assertions on it.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest
from indepdiag import TOLERANCE, Outcome, main_parameter_error, pair_in_order, timed_diagnose
from indepgen import (
    CATALOGUE,
    MAIN_PARAMETER,
    PAIRS,
    UNKNOWN,
    Generated,
    dwell_gain,
    make_trace,
    parameter_error,
    write_csv,
)

from gms_comp.app.commands.diagnose import summary

pytestmark = pytest.mark.slow  # every case runs the full diagnosis (tens of seconds each)

FIRST_SEED = 101
SEEDS = [FIRST_SEED + i for i in range(int(os.environ.get("GMS_INDEP_SEEDS", "1")))]
TIMEOUT_S = float(os.environ.get("GMS_INDEP_TIMEOUT_S", "900"))

_diagnosed: dict[tuple[str, int], tuple[Generated, Outcome]] = {}

# Cases the diagnosis misses today, measured (issue 15 stays open on them). Strict: the
# day one passes, the suite says so and the entry must go. KNOWN_MISSES: the name (and
# so the parameter too); KNOWN_PARAMETER_MISSES: named right, main parameter off.
KNOWN_MISSES: dict[tuple[str, int], str] = {}
KNOWN_PARAMETER_MISSES: dict[tuple[str, int], str] = {}


def grid(
    cases: list[str] | tuple[str, ...], misses: dict[tuple[str, int], str] = KNOWN_MISSES
) -> list[object]:
    """``(case, seed)`` parameters, the known ``misses`` marked strict xfail."""
    return [
        pytest.param(
            case,
            seed,
            id=f"{case}-{seed}",
            marks=[pytest.mark.xfail(strict=True, reason=misses[case, seed])]
            if (case, seed) in misses
            else [],
        )
        for case in cases
        for seed in SEEDS
    ]


@pytest.fixture(scope="session")
def trace_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One folder for every generated trace of the session."""
    return tmp_path_factory.mktemp("indep_traces")


def diagnosed(case: str, seed: int, folder: Path) -> tuple[Generated, Outcome]:
    """Generate ``case`` for ``seed``, diagnose it through the CLI (once per session)."""
    if (case, seed) not in _diagnosed:
        gen = make_trace(case, seed)
        path = write_csv(gen, folder / f"{case}_{seed}.csv")
        _diagnosed[case, seed] = gen, timed_diagnose(path, TIMEOUT_S)
    return _diagnosed[case, seed]


def _describe(gen: Generated, outcome: Outcome) -> str:
    return (
        f"{gen.case} seed {gen.seed}: truth {gen.effects} (C_v {gen.C_v:.3f}, "
        f"{gen.n_elements} elements, level {gen.sliding_force_N:.2f} N, "
        f"noise {gen.noise_N:.3f} N); diagnosis named {outcome.named!r}, "
        f"ranked {outcome.ranked}, parameters {outcome.result.get('parameters')}"
    )


@pytest.mark.parametrize(("effect", "seed"), grid(CATALOGUE))
def test_catalogue_effect_is_named_first(effect: str, seed: int, trace_dir: Path) -> None:
    gen, outcome = diagnosed(effect, seed, trace_dir)
    assert outcome.named == effect, _describe(gen, outcome)


@pytest.mark.parametrize(("effect", "seed"), grid(CATALOGUE, KNOWN_MISSES | KNOWN_PARAMETER_MISSES))
def test_catalogue_effect_main_parameter_within_tolerance(
    effect: str, seed: int, trace_dir: Path
) -> None:
    gen, outcome = diagnosed(effect, seed, trace_dir)
    error = main_parameter_error(gen, outcome)
    assert error is not None, f"{effect} not fitted: " + _describe(gen, outcome)
    judged = MAIN_PARAMETER[effect] if effect != "dwell_time" else "gain after the median dwell"
    assert error <= TOLERANCE[effect], (
        f"{judged} off by {error:.0%} (tolerance {TOLERANCE[effect]:.0%}): "
        + _describe(gen, outcome)
    )


@pytest.mark.parametrize("seed", SEEDS)
def test_effect_free_trace_is_none(seed: int, trace_dir: Path) -> None:
    gen, outcome = diagnosed("none", seed, trace_dir)
    assert outcome.named == "none", _describe(gen, outcome)


@pytest.mark.parametrize(("case", "seed"), grid(UNKNOWN))
def test_uncatalogued_effect_is_unknown(case: str, seed: int, trace_dir: Path) -> None:
    gen, outcome = diagnosed(case, seed, trace_dir)
    assert outcome.named == "unknown", _describe(gen, outcome)


@pytest.mark.parametrize(("case", "seed"), grid([f"pair_{big}_{small}" for big, small in PAIRS]))
def test_two_effects_are_ranked_larger_first(case: str, seed: int, trace_dir: Path) -> None:
    gen, outcome = diagnosed(case, seed, trace_dir)
    assert pair_in_order(gen, outcome), _describe(gen, outcome)


@pytest.mark.parametrize("seed", SEEDS)
def test_dwell_windows_are_computed_at_the_fitted_gain(seed: int, trace_dir: Path) -> None:
    # the raised limits' windows are those of the gain reported (the shape agrees with
    # the size, within the fixed point's 10 %), not of a gain the search passed through
    gen, outcome = diagnosed("dwell_time", seed, trace_dir)
    params = outcome.result.get("parameters") or {}
    if outcome.named != "dwell_time":
        pytest.skip("dwell_time not named (see test_catalogue_effect_is_named_first)")
    ratio = params["reach"] / params["gamma"]
    assert 1 / 1.1 <= ratio <= 1.1, _describe(gen, outcome)


@pytest.mark.parametrize("seed", SEEDS)
def test_a_dwell_gain_is_reported_after_the_trace_s_median_standstill(
    seed: int, trace_dir: Path
) -> None:
    # what a trace determines of a dwell gain: the break-away gain after its typical
    # standstill (gamma alone trades with tau); the median is the truth's, within 5 %
    gen, outcome = diagnosed("dwell_time", seed, trace_dir)
    if outcome.named != "dwell_time":
        pytest.skip("dwell_time not named (see test_catalogue_effect_is_named_first)")
    entry = next(e for e in outcome.result["effects"] if e["effect"] == "dwell_time")
    figures, fitted = entry["in_context"], entry["parameters"]
    truth = dict(gen.effects)["dwell_time"]
    assert figures["median_dwell_s"] == pytest.approx(truth["median_standstill_s"], rel=0.05)
    assert figures["gain_after_median_dwell"] == pytest.approx(
        dwell_gain(fitted, figures["median_dwell_s"]), rel=1e-9
    )


def test_a_small_dwell_gain_is_judged_by_its_significance(trace_dir: Path) -> None:
    # seed 118: a gain of 0.09 (peaks 3 x the noise): the fitted 0.11 lowers the RMS at
    # the starts by 18 % with z 4.7; the 20 % local margin before left it out
    gen, outcome = diagnosed("dwell_time", 118, trace_dir)
    assert outcome.named == "dwell_time", _describe(gen, outcome)


def test_a_dwell_gain_far_above_the_noise_at_the_starts_is_kept(trace_dir: Path) -> None:
    # seed 240: a gain of 0.13 after the median standstill, noise 1.4 % of the level; the
    # fitted gain lowered the RMS at the starts from 0.149 to 0.139 N only (noise 0.132 N)
    # with z 7.7, under the 15 % local margin; above the noise, 0.068 -> 0.043 N
    gen, outcome = diagnosed("dwell_time", 240, trace_dir)
    assert outcome.named == "dwell_time", _describe(gen, outcome)
    error = main_parameter_error(gen, outcome)
    assert error is not None and error <= TOLERANCE["dwell_time"], _describe(gen, outcome)


def test_a_dwell_gain_s_shape_is_not_settled_down_the_gain(trace_dir: Path) -> None:
    # seed 130 (gamma 0.24 at tau 0.42 s): the fitted coefficient sits below the gain the
    # windows are computed at, so making each shape agree exactly walked down the gain;
    # the agreed ridge's best lowered the RMS at the starts by 10 % (under the local
    # margin) and the answer was `none`. Shapes that agree within the factor do 20 %
    gen, outcome = diagnosed("dwell_time", 130, trace_dir)
    assert outcome.named == "dwell_time", _describe(gen, outcome)
    error = main_parameter_error(gen, outcome)
    assert error is not None and error <= TOLERANCE["dwell_time"], _describe(gen, outcome)


@pytest.mark.parametrize("seed", [113, 117, 197])
def test_a_ripple_of_few_periods_over_the_stroke_is_named(seed: int, trace_dir: Path) -> None:
    # 7.6 and 8.0 mm ripples on 21 and 13 mm strokes (2.8 and 1.6 periods): with the
    # wavelength bounded by a third of the stroke they came out `unknown`; 4.57 mm on a
    # 5.94 mm stroke (1.3 periods) did too with the bound at two thirds of it
    gen, outcome = diagnosed("position_ripple", seed, trace_dir)
    assert outcome.named == "position_ripple", _describe(gen, outcome)
    error = main_parameter_error(gen, outcome)
    assert error is not None and error <= TOLERANCE["position_ripple"], _describe(gen, outcome)


def test_a_large_ripple_is_left_out_when_the_elements_are_placed(trace_dir: Path) -> None:
    # seed 125: a 9.6 N ripple on a 36 N level. The elements placed with it in the force
    # left 1.3 N (3.4 x the noise) in the slow first quarter, read as a tone: `unknown`
    gen, outcome = diagnosed("position_ripple", 125, trace_dir)
    assert outcome.named == "position_ripple", _describe(gen, outcome)
    assert outcome.result["extended_rms_N"] <= 1.1 * gen.noise_N, _describe(gen, outcome)


@pytest.mark.parametrize(
    ("case", "seed"), [("position_ripple", 124), ("pair_position_ripple_inertia", 122)]
)
def test_a_ripple_s_wavelength_holds_its_phase_over_the_stroke(
    case: str, seed: int, trace_dir: Path
) -> None:
    # 124: 1.23 mm over 37 mm (30 periods); the grid's 0.17 % error moved the phase 0.26
    # rad over the stroke and left the held-out RMS 30 % above the noise. 122 (with a
    # mass): 4.86 mm for 4.93 (1.5 % off), the 8 % steps could not reach it
    gen, outcome = diagnosed(case, seed, trace_dir)
    assert outcome.named == "position_ripple", _describe(gen, outcome)
    truth = dict(gen.effects)["position_ripple"]["wavelength_m"]
    fitted = outcome.result["parameters"]["wavelength_m"]
    assert fitted == pytest.approx(truth, rel=5e-4), _describe(gen, outcome)


def test_a_ripple_the_elements_took_part_of_is_found_by_what_it_adds(trace_dir: Path) -> None:
    # pair_position_ripple_inertia-205: 4.88 mm, 9.0 N, with a 28 kg mass. The elements
    # placed with the ripple in the force take part of it, and the residual's own
    # projection on sin/cos peaked at 5.6-5.8 mm: the answer was `unknown`. Scanned for
    # what each wavelength adds to the design, the best scan point is 4.865 mm
    gen, outcome = diagnosed("pair_position_ripple_inertia", 205, trace_dir)
    assert pair_in_order(gen, outcome), _describe(gen, outcome)
    error = main_parameter_error(gen, outcome)
    assert error is not None and error <= TOLERANCE["position_ripple"], _describe(gen, outcome)


def test_a_stroke_profile_a_stribeck_fall_took_part_of_is_unknown(trace_dir: Path) -> None:
    # unknown_stroke_profile-249 (limits 1 + 0.33 u^2 over the stroke, 4.8 kHz): a
    # Stribeck fall with the slip level took part of it and left 3.9 x the noise, by
    # position alone 2.3 x the noise but 2.7 % of the sliding force, under the 3 %
    # threshold: `stribeck` until the residual as a whole was read (structure.py)
    gen, outcome = diagnosed("unknown_stroke_profile", 249, trace_dir)
    assert outcome.named == "unknown", _describe(gen, outcome)
    where = outcome.result["structure"]["description"]
    assert "x the noise" in where and "position" in where, where


@pytest.mark.parametrize("case", ["none", "dwell_time", "sensor_lowpass"])
def test_a_sensor_s_low_passed_noise_is_noise_not_an_unexplained_residual(
    case: str, trace_dir: Path
) -> None:
    # seed 242 (1.3 kHz, noise 3.0 % of the level) with its noise low-passed at 65 Hz:
    # read from the sample-to-sample differences it was 7.2 x smaller, the residual stood
    # 7.9 x "the noise", and dwell_time and sensor_lowpass were `unknown` (structure.py
    # reads the noise at rest as well)
    gen = make_trace(case, 242, noise_cutoff_Hz=65.0)
    outcome = timed_diagnose(write_csv(gen, trace_dir / f"{case}_242_coloured.csv"), TIMEOUT_S)
    assert outcome.named == gen.expected, _describe(gen, outcome)


def test_a_fast_trace_s_rare_single_counts_still_read_as_its_encoder(trace_dir: Path) -> None:
    # seed 261: a 2.05 nm encoder, single counts 0.014 % of the steps. Read as unquantised
    # (its resolution 0.55 um), the free GMS's smallest break-away was 1.09 um for the
    # truth's 0.27 um stiff element, and a reversal transient (2.7 N over 1.2 um, 62 % of
    # the level, at its length bound) stood in for it: reversal_transient on 16 of the
    # seed's 18 traces, the effect-free one first (encoder.py)
    gen, outcome = diagnosed("none", 261, trace_dir)
    assert outcome.named == "none", _describe(gen, outcome)
    assert outcome.result["baseline"]["breakaway_m"][0] < 0.5e-6


def test_a_stribeck_fall_shown_by_two_fast_moves_is_named(trace_dir: Path) -> None:
    # stribeck-260: a fall over v_s 7.45 mm/s (ratio 1.32) on a trace whose speeds are 77 %
    # below 1.8 mm/s; two moves reach 27 and 11 mm/s (1.2 % of the rows), mostly trained
    # on, the held-out rows up to 6.6 mm/s. Judged on the held-out rows alone (0.6 % lower)
    # it was not kept, and its fall read as a spot: `unknown`. Judged also where it departs
    # from the GMS force, each fast move by a fit without it (Effect.departure): named
    gen, outcome = diagnosed("stribeck", 260, trace_dir)
    assert outcome.named == "stribeck", _describe(gen, outcome)
    error = main_parameter_error(gen, outcome)
    assert error is not None and error <= TOLERANCE["stribeck"], _describe(gen, outcome)


def test_a_stribeck_fall_after_an_offset_is_ranked_second(trace_dir: Path) -> None:
    # pair_offset_stribeck-259: an offset of 30 % of the level, a fall of ratio 1.15 over
    # 3.4 mm/s; forward at 2.7 mm/s, back at 5-6 mm/s. With the GMS force the fall scales
    # fitted alone (part of the offset in its limits), a direction asymmetry held out
    # better and was ranked second (offset > direction_asymmetry); on the force fitted
    # beside the offset, offset > stribeck
    gen, outcome = diagnosed("pair_offset_stribeck", 259, trace_dir)
    assert pair_in_order(gen, outcome), _describe(gen, outcome)
    assert "direction_asymmetry" not in outcome.ranked, _describe(gen, outcome)
    fitted = outcome.fitted("stribeck")
    assert fitted is not None
    error = parameter_error("stribeck", dict(gen.effects)["stribeck"], fitted)
    assert error <= TOLERANCE["stribeck"], _describe(gen, outcome)


def test_a_term_dropped_under_the_floor_gives_its_share_back_to_the_level(
    trace_dir: Path,
) -> None:
    # pair_drift_offset-251 (kappa 0.30 over 11.6 s, a 2.44 N offset on a 41 N level, C_v
    # 1.256 reached on the rational approach over 0.33 mm/s): a viscous term kept fourth
    # carried the approach's slow rise, 0.68 N at most, under the floor; dropped without
    # searching the level again, drift > offset held out 0.653 N (noise 0.622 N) and a 3 %
    # Stribeck fall at 0.06 mm/s, bent into the onset, was kept third
    gen, outcome = diagnosed("pair_drift_offset", 251, trace_dir)
    assert outcome.ranked == ["drift", "offset"], _describe(gen, outcome)
    error = main_parameter_error(gen, outcome)
    assert error is not None and error <= TOLERANCE["drift"], _describe(gen, outcome)
    assert outcome.result["extended_rms_N"] < 1.03 * outcome.result["noise_rms_N"]


def test_a_transient_beside_a_drift_is_not_left_as_a_spot(trace_dir: Path) -> None:
    # pair_drift_reversal_transient-209 (kappa -0.30 over 16 s, a 1.28 N transient over
    # 0.12 mm): at 5da264b the transient came out 0 mm long and a spot it left (+0.58 N
    # over 0.125 mm) read `unknown`; since the ripple is scanned for what it adds to
    # the design (73498c9): drift > reversal_transient, 1.23 N over 0.10 mm
    gen, outcome = diagnosed("pair_drift_reversal_transient", 209, trace_dir)
    assert pair_in_order(gen, outcome), _describe(gen, outcome)
    error = main_parameter_error(gen, outcome)
    assert error is not None and error <= TOLERANCE["drift"], _describe(gen, outcome)


@pytest.mark.parametrize("seed", [105, 126, 130])
def test_a_stribeck_fall_is_sized_with_the_level_it_trades_against(
    seed: int, trace_dir: Path
) -> None:
    # 130: v_s chosen with the baseline's GMS force (9.5 mm/s for 5.6) left ratio - 1
    # 0.53 off; searched again with the refitted force, 0.02. 105, 126 (v_s 2.1, 2.2 mm/s,
    # C_v 1.28, 1.18): the blind baseline carried the fall with its slip level (C_v 1.0,
    # 1.05), and steps on the level, then on v_s, stalled 0.58 and 0.64 off; searched
    # together, 0.19 and 0.28
    gen, outcome = diagnosed("stribeck", seed, trace_dir)
    assert outcome.named == "stribeck", _describe(gen, outcome)
    error = main_parameter_error(gen, outcome)
    assert error is not None and error <= TOLERANCE["stribeck"], _describe(gen, outcome)


def test_a_stribeck_fall_above_a_slip_level_is_scored_with_the_level_free(
    trace_dir: Path,
) -> None:
    # seed 120 (C_v 1.14 over 0.35 mm/s, ratio 1.24 at 6.4 mm/s): the GMS alone fits best
    # at C_v 1, where a Stribeck column lowered the held-out RMS by 2.5 % only, and a
    # drift was named; with the level at C_v 1.1 it lowers it by half
    gen, outcome = diagnosed("stribeck", 120, trace_dir)
    assert outcome.named == "stribeck", _describe(gen, outcome)
    error = main_parameter_error(gen, outcome)
    assert error is not None and error <= TOLERANCE["stribeck"], _describe(gen, outcome)


def test_a_stribeck_fall_is_scored_at_a_transition_between_the_level_grid_s(
    trace_dir: Path,
) -> None:
    # pair_offset_stribeck-229 (C_v 1.136 over 0.64 mm/s, ratio 1.12 at 2.7 mm/s): on the
    # level-free grid's transition velocities (15 x apart) Stribeck held out 0.1902 N
    # beside drift's 0.1951 N, short of the margin, and offset was named alone; at the
    # best level's transition halfway to the next, 0.1723 N
    gen, outcome = diagnosed("pair_offset_stribeck", 229, trace_dir)
    assert pair_in_order(gen, outcome), _describe(gen, outcome)
    error = main_parameter_error(gen, outcome)
    assert error is not None and error <= TOLERANCE["offset"], _describe(gen, outcome)


def test_a_stribeck_that_only_moves_the_slip_level_is_not_kept(trace_dir: Path) -> None:
    # drift-122 (no Stribeck, C_v 1.219): the level-free search kept a Stribeck at C_v
    # 1.395 second (0.683 N held out against 0.734 N for the drift's design on the grid);
    # refitted without it from the selection's level, the drift alone fits better
    # (0.6455 against 0.6483 N), and the drift's kappa came out 0.261 (0.11 off)
    gen, outcome = diagnosed("drift", 122, trace_dir)
    assert outcome.ranked == ["drift"], _describe(gen, outcome)
    error = main_parameter_error(gen, outcome)
    assert error is not None and error <= 0.05, _describe(gen, outcome)


@pytest.mark.parametrize(
    ("case", "seed", "tolerance"), [("drift", 120, 0.05), ("reversal_transient", 251, None)]
)
def test_an_effect_that_stands_in_for_the_level_is_judged_by_the_refit_without_it(
    case: str, seed: int, tolerance: float | None, trace_dir: Path
) -> None:
    # drift-120 (no Stribeck): a Stribeck at the baseline's level was kept second after
    # the drift; refitted without it, the drift alone leaves 0.16598 N held out against
    # 0.16572 N with it, far short of the keep rule's margin.
    # reversal_transient-251 (an 11 N transient over 36 um on a 35 N level, C_v 1.256
    # reached on the rational approach; no drift): a 3 % drift over 6.3 s was chosen
    # first and kept beside the transient (0.713 N held out, noise 0.638 N); the transient
    # alone, its level searched, holds out 0.708 N at C_v 1.252
    gen, outcome = diagnosed(case, seed, trace_dir)
    assert outcome.ranked == [case], _describe(gen, outcome)
    error = main_parameter_error(gen, outcome)
    assert error is not None and error <= (tolerance or TOLERANCE[case]), _describe(gen, outcome)


def test_a_drift_is_sized_with_the_level_it_trades_against(trace_dir: Path) -> None:
    # 109 (kappa 0.278 over 9.96 s, C_v 1.23): the blind baseline's level was placed on the
    # growing force (C_v 1.37), and the refits stopped at 0.199 over 5.5 s (0.28 off);
    # tau searched with the level, 0.276 over 9.92 s
    gen, outcome = diagnosed("drift", 109, trace_dir)
    assert outcome.named == "drift", _describe(gen, outcome)
    error = main_parameter_error(gen, outcome)
    assert error is not None and error <= 0.1, _describe(gen, outcome)


def test_a_mass_is_fitted_where_the_acceleration_is_large(trace_dir: Path) -> None:
    # 124: both 7.4 m/s^2 ramps fell in held-out blocks (the training rows reached 0.55),
    # and the mass fitted on sines in presliding came out 0.33 kg for 0.42 (0.21 off)
    gen, outcome = diagnosed("inertia", 124, trace_dir)
    assert outcome.named == "inertia", _describe(gen, outcome)
    error = main_parameter_error(gen, outcome)
    assert error is not None and error <= 0.05, _describe(gen, outcome)


def test_a_mass_on_short_ramps_is_not_fitted_high(trace_dir: Path) -> None:
    # 239 (1 kHz, half the acceleration's energy above 50 Hz): on the benchmark's
    # five-sample second difference, 0.543 kg for 0.469 (0.16 off)
    gen, outcome = diagnosed("inertia", 239, trace_dir)
    assert outcome.named == "inertia", _describe(gen, outcome)
    error = main_parameter_error(gen, outcome)
    assert error is not None and error <= 0.08, _describe(gen, outcome)


@pytest.mark.parametrize(("seed", "confounded"), [(119, True), (101, False)])
def test_a_trace_that_cannot_tell_speed_from_direction_says_so(
    seed: int, confounded: bool, trace_dir: Path
) -> None:
    # seed 119's step-and-stop holds two moves: forward at 6.9 mm/s, back at 1.2 mm/s.
    # Its hidden Stribeck fall is named direction_asymmetry (both fit the held-out rows
    # within 3 %); the answer must say that this trace could not tell them apart. Seed
    # 101 moves at several speeds both ways: no such caveat.
    gen, outcome = diagnosed("stribeck", seed, trace_dir)
    kinds = {c["kind"]: c for c in outcome.result["caveats"]}
    assert ("speed_direction" in kinds) == confounded, _describe(gen, outcome)
    if confounded:
        # the fit's own near tie says it too: the truth came near the effect named
        assert kinds["near_tie"]["effects"] == [outcome.named, "stribeck"], kinds["near_tie"]
        caveat = kinds["speed_direction"]
        assert {"stribeck", "direction_asymmetry", outcome.named} <= set(caveat["effects"])
        bands = re.findall(r"(forward|back) at ([\d.]+)-([\d.]+) mm/s", caveat["text"])
        speeds = {"forward": 6.9, "back": 1.2}  # the generator's moves (mm/s)
        assert len(bands) == 2, caveat["text"]
        for way, lo, hi in bands:
            assert float(lo) <= speeds[way] <= float(hi), caveat["text"]
    text = summary({**outcome.result, "trace": f"stribeck-{seed}"}, gen.time_s.size, "friction")
    assert ("caveat: speed and direction go together" in text) == confounded, text


@pytest.mark.parametrize(("seed", "order"), [(122, 3), (128, 3), (142, 3), (185, 4), (188, 3)])
def test_a_sensor_filter_s_order_is_decided_by_its_own_cutoff(
    seed: int, order: int, trace_dir: Path
) -> None:
    # 122, 128: third-order filters fitted as fourth-order at a grid cut-off 28 % high (the
    # order was the one whose grid point fell nearest the filter's delay); 185, 188: one
    # order off, 20 and 29 % in cut-off (the true order's grid best was not refined);
    # 142: `unknown` (the blind elements had bent to the filter's lag)
    gen, outcome = diagnosed("sensor_lowpass", seed, trace_dir)
    assert outcome.named == "sensor_lowpass", _describe(gen, outcome)
    fitted = outcome.fitted("sensor_lowpass") or {}
    assert fitted.get("order") == order, _describe(gen, outcome)
    error = main_parameter_error(gen, outcome)
    assert error is not None and error <= TOLERANCE["sensor_lowpass"], _describe(gen, outcome)


@pytest.mark.parametrize("seed", [123, 130, 229])
def test_friction_bumps_off_the_held_out_blocks_or_narrow_are_unknown(
    seed: int, trace_dir: Path
) -> None:
    # 123: the bumps are crossed outside the held-out blocks; 130: 0.12 mm wide, 5 x the
    # noise in 0.25 mm bins; 229: crossed once, one way only (-2.1 N, no bin the other
    # way to check it against). All three were `none`
    gen, outcome = diagnosed("unknown_bumps", seed, trace_dir)
    assert outcome.named == "unknown", _describe(gen, outcome)
    assert "locally" in outcome.result["structure"]["description"], _describe(gen, outcome)
