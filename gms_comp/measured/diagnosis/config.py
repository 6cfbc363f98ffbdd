"""The ``[diagnosis]`` section and its sub-sections: every threshold of the diagnosis, with
its unit (in its name), its range and one line of why (docs/config.md lists them;
docs/diagnosis-method.md says where each acts). The defaults were set on the independent
generator's traces (tests/indepgen.py); the rates they give are in docs/diagnosis.md."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from gms_comp.config import in_range, key, parse_section, positive, read_toml

UNIT = in_range(0.0, 1.0)
RATIO = in_range(1.0, 1e3)


@dataclass(frozen=True)
class SplitConfig:
    """The ``[diagnosis.split]`` section: held-out rows, usable traces, the noise at rest."""

    # fmt: off
    held_starts_share: float = key(0.5, UNIT, "the held-out third holds this share of a "
                                   "third of the starts after a standstill (a dwell gain's)")
    train_top_share: float = key(0.8, UNIT, "held-out blocks alone reaching this share of the "
                                 "top speed or acceleration are trained on: no extrapolation")
    held_top_share: float = key(0.2, UNIT, "held-out rows under this share of the top speed "
                                "get half the fast training rows (a fall is judged there)")
    max_fitted_every: int = key(2, in_range(1, 16), "at most every k-th sample fitted: a "
                                "dwell gain lives in a break-away's few samples")
    min_reversals: int = key(2, in_range(1, 1000), "a trace must reverse this often "
                             "(presliding after reversals carries the elements)")
    min_speed_spread: float = key(1.5, RATIO, "moving speeds (90th over 10th percentile) "
                                  "spread this much, to tell velocity laws apart")
    acceleration_noise_share: float = key(0.03, in_range(1e-4, 1.0), "the acceleration is "
                                          "low-passed where its quantisation noise is this "
                                          "share of it (a mass on noise comes out low)")
    rest_run_samples: int = key(50, in_range(3, 10**6), "the noise at rest is read on "
                                "standstills of this many samples or more")
    rest_samples: int = key(1000, in_range(10, 10**8), "... from this many in all (else the "
                            "second differences alone)")
    # fmt: on


@dataclass(frozen=True)
class SelectionConfig:
    """The ``[diagnosis.selection]`` section: when an extension is worth keeping.

    The one criterion of docs/diagnosis-method.md, section 2."""

    # fmt: off
    margin: float = key(0.05, UNIT, "kept if the held-out RMS falls by this share: noise and "
                        "baseline mismatch must not make effects")
    small_margin: float = key(0.01, UNIT, "... or by this share with z >= significance_t (a "
                              "small, consistent gain)")
    significance_t: float = key(4.0, in_range(0.0, 1e3), "z of the drop in squared residual "
                                "over its spread across chunks: chance out of many trials")
    significance_chunks: int = key(50, in_range(2, 10**4), "contiguous chunks the spread is "
                                   "read over (the residual is correlated in time)")
    local_share: float = key(0.25, UNIT, "an effect acting on fewer held-out rows is judged "
                             "where it acts, each event left out of its fit")
    local_margin: float = key(0.15, UNIT, "... lowering what stands above the noise there by "
                              "this share")
    local_significance_t: float = key(3.0, in_range(0.0, 1e3), "... with z at least this "
                                      "(effect-free traces' best dwell gain: z <= 2.1)")
    support_energy: float = key(0.9, UNIT, "where an effect acts: the fewest rows holding this "
                                "share of its columns' energy")
    support_level: float = key(0.1, UNIT, "... of those, the rows at this share of its peak or "
                               "more (not a raised element's tail)")
    event_gap_s: float = key(0.02, in_range(0.0, 1e3), "rows where an effect acts closer than "
                             "this are one event")
    left_out_folds: int = key(10, in_range(2, 1000), "events are dealt into this many folds, "
                              "each predicted by a fit without it")
    min_effect_fraction: float = key(0.02, UNIT, "an effect changes the force by this share of "
                                     "the sliding force somewhere (else it does not matter)")
    consistent_within: float = key(1.5, RATIO, "a shape that follows its size (a dwell's "
                                   "windows) agrees with it within this factor")
    free_level_ratio: float = key(1.15, RATIO, "an effect trading with the slip level is "
                                  "scored at other levels where this many x the noise is left")
    free_level_rounds: int = key(2, in_range(0, 9), "... in the first rounds only (a later "
                                 "effect is small; its level is the refit's)")
    # fmt: on


@dataclass(frozen=True)
class StructureConfig:
    """The ``[diagnosis.structure]`` section: when what is left is structure (unknown)."""

    # fmt: off
    unknown_ratio: float = key(1.5, positive(1e3), "a part of the residual (bin means less the "
                               "noise's share) this many x the noise is structure")
    unknown_fraction: float = key(0.03, UNIT, "... and this share of the sliding force (named "
                                  "traces left <= 1.9 %, uncatalogued >= 3.7 %)")
    unexplained_ratio: float = key(3.0, positive(1e3), "the residual as a whole this many x the "
                                   "noise is structure too (two quantities at once)")
    tone_prominence: float = key(30.0, positive(1e6), "a tone's peak stands this far above the "
                                 "spectrum's median")
    spot_width_m: float = key(0.125e-3, positive(1.0), "a spot is read over this much travel one "
                              "way (bumps are 0.1-0.45 mm)")
    spot_min_samples: int = key(30, in_range(1, 10**6), "a spot needs this many samples in "
                                "its bin")
    spot_z: float = key(8.0, positive(1e3), "... its mean this many standard errors from zero "
                        "(read on every sample: hundreds of bins)")
    spot_ratio: float = key(6.0, positive(1e3), "... and this many x the noise (catalogue traces: "
                            "<= 3.7 x)")
    spot_fraction: float = key(0.12, in_range(0.0, 10.0), "... and this share of the sliding "
                               "force (catalogue traces: <= 4.9 %)")
    spot_partner_z: float = key(3.0, positive(1e3), "friction acts both ways: the bin the other "
                                "way holds the other sign this significantly")
    spot_partner_samples: int = key(5, in_range(1, 10**6), "the other way counts as travelled "
                                    "from this many samples")
    spot_one_way_samples: int = key(10, in_range(1, 10**6), "a spot crossed one way only is "
                                    "read from this many steady samples")
    # fmt: on


@dataclass(frozen=True)
class CaveatConfig:
    """The ``[diagnosis.caveats]`` section: what a trace's motion cannot tell apart."""

    # fmt: off
    band_share: float = key(0.02, UNIT, "a speed band holds this share of a direction's "
                            "moving time")
    narrow_band: float = key(2.0, RATIO, "a band narrower than this factor is one speed for "
                             "a fit")
    near_tie: float = key(0.9, UNIT, "another effect that took this share of the first one's "
                          "drop is a near tie")
    at_bound: float = key(1.02, in_range(1.0, 10.0), "a shape within this factor of its "
                          "search bound is at it")
    # fmt: on


@dataclass(frozen=True)
class IntervalConfig:
    """The ``[diagnosis.intervals]`` section: how sure each fitted parameter is."""

    # fmt: off
    level: float = key(0.95, in_range(0.5, 0.999), "the intervals' confidence level")
    jackknife_blocks: int = key(20, in_range(3, 1000), "contiguous blocks of training rows "
                                "left out in turn: the noise's correlation, the misfit")
    model_form_share: float = key(0.06, UNIT, "each interval is at least this share of its "
                                  "parameter's size: the model's form, which no fit sees")
    # fmt: on


@dataclass(frozen=True)
class DetectionConfig:
    """The ``[diagnosis.detection]`` section: the smallest effects the trace would reveal."""

    # fmt: off
    shapes: int = key(3, in_range(1, 20), "shapes of an effect's grid its limit is worked "
                      "out at (the one stated: the median)")
    bisections: int = key(10, in_range(2, 100), "halvings (in log) of a factor-2 bracket: "
                          "the limit to 0.1 %")
    # fmt: on


@dataclass(frozen=True)
class DiagnosisConfig:
    """The ``[diagnosis]`` section: what the diagnosis fits, and how finely.

    Its thresholds are in the sub-sections (``[diagnosis.selection]`` ...)."""

    # fmt: off
    filter_cutoff_Hz: float = key(0.0, in_range(0.0, 1e9), "position low-pass; 0: almost none "
                                  "for a friction force, 100 Hz for a drive force")
    fit_rate_Hz: float = key(600.0, in_range(0.0, 1e9), "a trace sampled at twice this or "
                             "faster is fitted on every k-th sample (judged on all)")
    encoder_noise_ratio: float = key(0.7, in_range(0.0, 1e9), "counts read as motion where a "
                                     "count moves the GMS this many x the noise")
    n_elements: int = key(16, in_range(1, 40), "elements of the free GMS, dense where a "
                          "coarse pass of 8 found the limits")
    n_blocks: int = key(60, in_range(3, 1000), "contiguous blocks, every third held out: both "
                        "parts hold every kind of motion")
    max_effects: int = key(6, in_range(1, 9), "most effects kept (rounds of the forward "
                           "selection)")
    standstill_speed_fraction: float = key(0.01, UNIT, "below this share of the top speed the "
                                           "axis stands still")
    reversal_deadband_steps: float = key(0.6, in_range(0.0, 1e3), "a reversal: a retreat of "
                                         "more than this many position steps")
    rest_band_steps: float = key(1.5, in_range(0.0, 1e3), "a standstill ends where the "
                                 "position leaves this many steps around it")
    table_margin: float = key(0.1, in_range(0.0, 10.0), "a calibrated table is the baseline "
                              "within this share of the free GMS's held-out RMS")
    split: SplitConfig = field(default_factory=SplitConfig)
    selection: SelectionConfig = field(default_factory=SelectionConfig)
    structure: StructureConfig = field(default_factory=StructureConfig)
    caveats: CaveatConfig = field(default_factory=CaveatConfig)
    intervals: IntervalConfig = field(default_factory=IntervalConfig)
    detection: DetectionConfig = field(default_factory=DetectionConfig)
    # fmt: on


def load_diagnosis_config(path: str | Path | None) -> DiagnosisConfig:
    """The ``[diagnosis]`` section of the config file ``path`` (defaults without one)."""
    if path is None:
        return DiagnosisConfig()
    return parse_section(read_toml(path), path, "diagnosis", DiagnosisConfig)
