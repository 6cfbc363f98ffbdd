"""The ``[diagnosis]`` section and its sub-sections: every threshold of the diagnosis, with
its unit (in its name), its range and one line of why (docs/config.md lists them;
docs/diagnosis-method.md says where each acts). The defaults were set on the independent
generator's traces (tests/indepgen.py); the rates they give are in docs/diagnosis.md."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from gms_comp.config import in_range, parse_section, positive, read_toml, why


@dataclass(frozen=True)
class SplitConfig:
    """The ``[diagnosis.split]`` section: held-out rows, usable traces, the noise at rest."""

    held_starts_share: float = field(
        default=0.5,
        metadata=in_range(0.0, 1.0)
        | why(
            "the held-out third keeps this share of a third of the starts after a standstill "
            "(a dwell gain acts only there), else the third nearest a third is held out"
        ),
    )
    train_top_share: float = field(
        default=0.8,
        metadata=in_range(0.0, 1.0)
        | why(
            "held-out blocks that alone reach this share of the top speed or acceleration are "
            "trained on: a velocity law or a mass must not be extrapolated to where it is judged"
        ),
    )
    held_top_share: float = field(
        default=0.2,
        metadata=in_range(0.0, 1.0)
        | why(
            "held-out rows that do not reach this share of the top speed get half of the fast "
            "training rows (a fall at a trace's only fast moves must be judged there)"
        ),
    )
    max_fitted_every: int = field(
        default=2,
        metadata=in_range(1, 16)
        | why(
            "at most every k-th sample fitted (fit_rate_Hz): a dwell gain lives in a "
            "break-away's few samples"
        ),
    )
    min_reversals: int = field(
        default=2,
        metadata=in_range(1, 1000)
        | why("a trace must reverse this often: presliding after reversals carries the elements"),
    )
    min_speed_spread: float = field(
        default=1.5,
        metadata=in_range(1.0, 1e3)
        | why(
            "moving speeds (90th over 10th percentile) must spread this much to tell "
            "velocity laws apart"
        ),
    )
    acceleration_noise_share: float = field(
        default=0.03,
        metadata=in_range(1e-4, 1.0)
        | why(
            "a friction force's acceleration is low-passed where its quantisation noise is "
            "this share of its RMS (a mass fitted on noise comes out low)"
        ),
    )
    rest_run_samples: int = field(
        default=50,
        metadata=in_range(3, 10**6)
        | why("the noise at rest is read on standstills of this many samples or more"),
    )
    rest_samples: int = field(
        default=1000,
        metadata=in_range(10, 10**8)
        | why("... from this many samples in all (else the second differences alone)"),
    )


@dataclass(frozen=True)
class SelectionConfig:
    """The ``[diagnosis.selection]`` section: when an extension is worth keeping.

    The one criterion of docs/diagnosis-method.md, section 2."""

    margin: float = field(
        default=0.05,
        metadata=in_range(0.0, 1.0)
        | why(
            "kept if the held-out RMS falls by this share: noise and baseline mismatch must "
            "not make effects"
        ),
    )
    small_margin: float = field(
        default=0.01,
        metadata=in_range(0.0, 1.0)
        | why(
            "... or by this share with z >= significance_t: a small consistent gain, diluted "
            "by an unexplained part"
        ),
    )
    significance_t: float = field(
        default=4.0,
        metadata=in_range(0.0, 1e3)
        | why(
            "z of the drop in squared residual over its spread across chunks; 4 keeps chance "
            "out of hundreds of trials"
        ),
    )
    significance_chunks: int = field(
        default=50,
        metadata=in_range(2, 10**4)
        | why(
            "contiguous chunks the drop's spread is read over (residuals are correlated in "
            "time, chunks much less so)"
        ),
    )
    local_share: float = field(
        default=0.25,
        metadata=in_range(0.0, 1.0)
        | why(
            "an effect acting on fewer held-out rows than this share is judged where it acts, "
            "every event left out of its own fit"
        ),
    )
    local_margin: float = field(
        default=0.15,
        metadata=in_range(0.0, 1.0)
        | why("... and must lower what stands above the noise there by this share"),
    )
    local_significance_t: float = field(
        default=3.0,
        metadata=in_range(0.0, 1e3)
        | why("... with z at least this (effect-free traces' best dwell gain: z <= 2.1)"),
    )
    support_energy: float = field(
        default=0.9,
        metadata=in_range(0.0, 1.0)
        | why("where an effect acts: the fewest rows holding this share of its columns' energy"),
    )
    support_level: float = field(
        default=0.1,
        metadata=in_range(0.0, 1.0)
        | why(
            "... of which those at least this share of its peak (a raised element's tail "
            "through a standstill is not where it acts)"
        ),
    )
    event_gap_s: float = field(
        default=0.02,
        metadata=in_range(0.0, 1e3)
        | why("rows where an effect acts closer than this are one event"),
    )
    left_out_folds: int = field(
        default=10,
        metadata=in_range(2, 1000)
        | why("events are dealt into this many folds, each predicted by a fit without it"),
    )
    min_effect_fraction: float = field(
        default=0.02,
        metadata=in_range(0.0, 1.0)
        | why(
            "an effect must change the model force by this share of the sliding force "
            "somewhere (smaller terms do not matter for compensation)"
        ),
    )
    consistent_within: float = field(
        default=1.5,
        metadata=in_range(1.0, 1e3)
        | why(
            "a shape that follows its size (a dwell's windows) must agree with it within "
            "this factor"
        ),
    )
    free_level_ratio: float = field(
        default=1.15,
        metadata=in_range(1.0, 1e3)
        | why(
            "an effect that trades with the slip level is scored at other levels only where "
            "the design leaves this many times the noise"
        ),
    )
    free_level_rounds: int = field(
        default=2,
        metadata=in_range(0, 9)
        | why("... in the first rounds only (a later effect is small; its level is the refit's)"),
    )


@dataclass(frozen=True)
class StructureConfig:
    """The ``[diagnosis.structure]`` section: when what is left is structure (unknown)."""

    unknown_ratio: float = field(
        default=1.5,
        metadata=positive()
        | why(
            "a part of the residual (bin means, less the noise's share) this many times the "
            "noise is structure"
        ),
    )
    unknown_fraction: float = field(
        default=0.03,
        metadata=in_range(0.0, 1.0)
        | why(
            "... and at least this share of the sliding force (named traces left <= 1.9 %, "
            "uncatalogued ones >= 3.7 %)"
        ),
    )
    unexplained_ratio: float = field(
        default=3.0,
        metadata=positive()
        | why(
            "the residual as a whole this many times the noise is structure too (two "
            "quantities at once)"
        ),
    )
    tone_prominence: float = field(
        default=30.0,
        metadata=positive()
        | why("a tone counts when its peak stands this far above the spectrum's median"),
    )
    spot_width_m: float = field(
        default=0.125e-3,
        metadata=positive()
        | why("a spot is read over this much travel in one direction (bumps are 0.1-0.45 mm)"),
    )
    spot_min_samples: int = field(
        default=30, metadata=in_range(1, 10**6) | why("a spot needs this many samples in its bin")
    )
    spot_z: float = field(
        default=8.0,
        metadata=positive()
        | why(
            "... and its mean this many standard errors from zero (on every sample: hundreds "
            "of bins)"
        ),
    )
    spot_ratio: float = field(
        default=6.0,
        metadata=positive() | why("... and this many times the noise (catalogue traces: <= 3.7 x)"),
    )
    spot_fraction: float = field(
        default=0.12,
        metadata=in_range(0.0, 10.0)
        | why("... and this share of the sliding force (catalogue traces: <= 4.9 %)"),
    )
    spot_partner_z: float = field(
        default=3.0,
        metadata=positive()
        | why(
            "friction acts both ways: the bin the other way (or the next one the same way, if "
            "crossed once) holds the matching sign this significantly"
        ),
    )
    spot_partner_samples: int = field(
        default=5,
        metadata=in_range(1, 10**6)
        | why("the other way counts as travelled from this many samples"),
    )
    spot_one_way_samples: int = field(
        default=10,
        metadata=in_range(1, 10**6)
        | why("a spot crossed one way only is read from this many steady samples"),
    )


@dataclass(frozen=True)
class CaveatConfig:
    """The ``[diagnosis.caveats]`` section: what a trace's motion cannot tell apart."""

    band_share: float = field(
        default=0.02,
        metadata=in_range(0.0, 1.0)
        | why("a speed band holds this share of a direction's moving time"),
    )
    narrow_band: float = field(
        default=2.0,
        metadata=in_range(1.0, 1e3)
        | why("a band narrower than this factor is one speed for a fit"),
    )
    near_tie: float = field(
        default=0.9,
        metadata=in_range(0.0, 1.0)
        | why("another effect that took this share of the first one's drop is a near tie"),
    )
    at_bound: float = field(
        default=1.02,
        metadata=in_range(1.0, 10.0)
        | why("a shape within this factor of its search bound is at it"),
    )


@dataclass(frozen=True)
class IntervalConfig:
    """The ``[diagnosis.intervals]`` section: how sure each fitted parameter is."""

    level: float = field(
        default=0.95, metadata=in_range(0.5, 0.999) | why("the intervals' confidence level")
    )
    jackknife_blocks: int = field(
        default=20,
        metadata=in_range(3, 1000)
        | why(
            "contiguous blocks of the training rows left out in turn: they carry the noise's "
            "correlation and the misfit along the trace"
        ),
    )
    misfit_patterns: float = field(
        default=20.0,
        metadata=in_range(1.0, 1e9)
        | why(
            "the misfit left above the noise, spread over this many independent patterns, is "
            "how far a parameter may be off beyond the jackknife (1: the worst case)"
        ),
    )


@dataclass(frozen=True)
class DetectionConfig:
    """The ``[diagnosis.detection]`` section: the smallest effects the trace would reveal."""

    shapes: int = field(
        default=3,
        metadata=in_range(1, 20)
        | why(
            "shapes of each effect's grid the limit is worked out at (the stated limit is at "
            "the median one)"
        ),
    )
    bisections: int = field(
        default=10,
        metadata=in_range(2, 100)
        | why("halvings (in log) of the size bracket, a factor 2 wide: the limit to 0.1 %"),
    )


@dataclass(frozen=True)
class DiagnosisConfig:
    """The ``[diagnosis]`` section: what the diagnosis fits, and how finely.

    Its thresholds are in the sub-sections (``[diagnosis.selection]`` ...)."""

    filter_cutoff_Hz: float = field(
        default=0.0,
        metadata=in_range(0.0, 1e9)
        | why(
            "position low-pass; 0: almost none for a friction force, the EMPS benchmark's "
            "100 Hz for a drive force"
        ),
    )
    fit_rate_Hz: float = field(
        default=600.0,
        metadata=in_range(0.0, 1e9)
        | why(
            "a trace sampled at twice this or faster is fitted on every k-th sample (halves "
            "the time); judged on every sample"
        ),
    )
    encoder_noise_ratio: float = field(
        default=0.7,
        metadata=in_range(0.0, 1e9)
        | why(
            "the counts are read as motion where a count's error moves the GMS this many "
            "times the noise and that holds out better"
        ),
    )
    n_elements: int = field(
        default=16,
        metadata=in_range(1, 40)
        | why("elements of the free GMS, dense where a coarse pass of 8 found the limits"),
    )
    n_blocks: int = field(
        default=60,
        metadata=in_range(3, 1000)
        | why("contiguous blocks, every third held out: both parts hold every kind of motion"),
    )
    max_effects: int = field(
        default=6,
        metadata=in_range(1, 9) | why("most effects kept (rounds of the forward selection)"),
    )
    standstill_speed_fraction: float = field(
        default=0.01,
        metadata=in_range(0.0, 1.0)
        | why("below this share of the top speed the axis stands still"),
    )
    reversal_deadband_steps: float = field(
        default=0.6,
        metadata=in_range(0.0, 1e3)
        | why(
            "a reversal is a retreat of more than this many position steps (1 and more for "
            "an encoder that dithers)"
        ),
    )
    rest_band_steps: float = field(
        default=1.5,
        metadata=in_range(0.0, 1e3)
        | why("a standstill ends when the position leaves this many steps around its rest"),
    )
    table_margin: float = field(
        default=0.1,
        metadata=in_range(0.0, 10.0)
        | why(
            "a calibrated table is the baseline within this share of the free GMS's held-out "
            "RMS (its parameters mean something)"
        ),
    )
    split: SplitConfig = field(default_factory=SplitConfig)
    selection: SelectionConfig = field(default_factory=SelectionConfig)
    structure: StructureConfig = field(default_factory=StructureConfig)
    caveats: CaveatConfig = field(default_factory=CaveatConfig)
    intervals: IntervalConfig = field(default_factory=IntervalConfig)
    detection: DetectionConfig = field(default_factory=DetectionConfig)


def load_diagnosis_config(path: str | Path | None) -> DiagnosisConfig:
    """The ``[diagnosis]`` section of the config file ``path`` (defaults without one)."""
    if path is None:
        return DiagnosisConfig()
    return parse_section(read_toml(path), path, "diagnosis", DiagnosisConfig)
