"""Stage 3: the catalogue effects as candidate extensions of the baseline's design.

An :class:`Option` is a catalogue effect with its shape fixed: extra design columns (the
coefficients' bound from its policy) or a filter of every column. A :class:`Scorer` holds
the design of the effects chosen so far and scores one more option on it by held-out RMS
(its training Gram matrix reused, :class:`~.design.GramDesign`).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from gms_comp.measured.diagnosis.baseline import FittedPart
from gms_comp.measured.diagnosis.config import SelectionConfig
from gms_comp.measured.diagnosis.design import (
    BATCH_COLUMNS,
    BoolArray,
    Columns,
    FloatArray,
    GramDesign,
    IntArray,
    PartDesign,
    every_row,
    rms,
    runs,
)
from gms_comp.measured.policies import Leftover, Policy, policy
from gms_comp.runtime import effects as fx

# The columns of this many options are kept by a Scorer (one round of the selection).
COLUMNS_KEPT = 32


@dataclass(frozen=True)
class Option:
    """An effect with fixed shape: how it changes the design."""

    effect: type[fx.Effect]
    shape: dict[str, float]

    @property
    def policy(self) -> type[Policy]:
        """The effect's diagnosis policy."""
        return policy(self.effect)

    @property
    def is_filter(self) -> bool:
        """Whether the effect filters the whole force."""
        return issubclass(self.effect, fx.FilterEffect)

    def filter_effect(self) -> fx.FilterEffect:
        """The filter this option is (only for a filter option)."""
        assert issubclass(self.effect, fx.FilterEffect)
        return self.effect.from_shape(self.shape)

    def columns(self, fp: FittedPart, filters: Sequence[Option] = ()) -> Columns:
        """The additive option's columns on ``fp``, through the chosen ``filters``."""
        values = through(filters, fp.effect_basis(self.effect, self.shape), fp.ctx.sample_time_s)
        return Columns(values, np.full(values.shape[1], self.policy.coefficient_lower))

    def acting(self, fp: FittedPart, columns: Columns) -> FloatArray:
        """Values along ``fp`` whose large rows are where the option acts: its
        ``columns`` there, or the effect's own departure from the baseline."""
        departure = self.policy.departure(fp.ctx, self.shape)
        return columns.values if departure is None else departure[:, None]

    def with_value(self, key: str, value: float) -> Option:
        """The option with one shape parameter changed."""
        return Option(self.effect, {**self.shape, key: value})


def through(filters: Sequence[Option], values: FloatArray, sample_time_s: float) -> FloatArray:
    """``values`` (samples along axis 0) through the filter options ``filters`` in order."""
    for f in filters:
        values = f.filter_effect().filter_columns(values, sample_time_s)
    return values


def options(effect: type[fx.Effect], scorer: Scorer, presliding_m: float) -> list[Option]:
    """The effect's shape grid on the main part as options, searched in what the design
    of ``scorer`` leaves (:attr:`Scorer.leftover`) where the effect reads it."""
    rules = policy(effect)
    left = scorer.leftover if rules.reads_leftover else Leftover.empty()
    grid = rules.shape_grid(scorer.parts[0].ctx, left, presliding_m)
    return [Option(effect, s) for s in grid]


def design(parts: Sequence[FittedPart], chosen: Sequence[Option]) -> list[PartDesign]:
    """Each part's design with the ``chosen`` options (filters applied last, to all)."""
    filters = [o for o in chosen if o.is_filter]
    out = []
    for fp in parts:
        cols = Columns(through(filters, fp.base.values, fp.ctx.sample_time_s), fp.base.lower)
        additive = [opt.columns(fp, filters) for opt in chosen if not opt.is_filter]
        cols = Columns.join([cols, *additive])
        out.append(PartDesign(cols, fp.part.force_N, fp.part.train, fp.part.held))
    return out


@dataclass(frozen=True)
class Trial:
    """One option scored on the design of the chosen ones."""

    option: Option
    heldout_rms_N: float
    theta: FloatArray
    held_residual_N: FloatArray
    acting: Callable[[], BoolArray] = field(repr=False, compare=False)

    @functools.cached_property
    def support(self) -> BoolArray:
        """The held-out rows where the option acts, worked out when first asked (of a
        grid's trials, the best one's alone is)."""
        return self.acting()


class Scorer:
    """Trials of one more option on top of the design of ``chosen``.

    Parameters
    ----------
    parts
        The baseline's parts (their path contexts carry the GMS force to scale).
    chosen
        The options kept so far.
    rules
        Where an option acts and how its events are left out (``[diagnosis.selection]``).
    every_sample
        When the parts are every k-th sample of the trace: the same parts along every
        sample (made when first asked), where an effect at few events is judged
        (:attr:`judge`).
    """

    def __init__(
        self, parts: Sequence[FittedPart], chosen: Sequence[Option], rules: SelectionConfig,
        every_sample: Callable[[], Sequence[FittedPart]] | None = None,
    ) -> None:  # fmt: skip
        self._every_sample = every_sample
        self.rules = rules
        self.parts = tuple(parts)
        self.chosen = tuple(chosen)
        self.filters = [o for o in chosen if o.is_filter]
        self.designs = design(parts, chosen)
        self.gram = GramDesign(self.designs)
        self.theta = self.gram.fit()
        self.held_residual_N = self.gram.held_residual(self.theta)
        self.heldout_rms_N = rms(self.held_residual_N)
        self._all_held = np.ones(self.held_residual_N.size, dtype=bool)
        self._whole: GramDesign | None = None
        self._columns: dict[tuple[object, ...], list[Columns]] = {}

    @functools.cached_property
    def judge(self) -> Scorer:
        """The scorer on every sample of the trace (the same design), where an effect at
        few events is judged by :meth:`left_out` (picked, a dwell gain's z at its few
        starts halves); this one when the parts are every sample."""
        if self._every_sample is None:
            return self
        return Scorer(self._every_sample(), self.chosen, self.rules)

    def model(self, index: int = 0) -> FloatArray:
        """The current design's force on part ``index``."""
        return self.designs[index].columns.values @ self.theta

    @functools.cached_property
    def leftover(self) -> Leftover:
        """What the design leaves on the main part's training rows in motion, with the
        design's basis there (for a grid found from it: a ripple's wavelengths)."""
        fp = self.parts[0]
        residual = fp.part.force_N - self.model()
        read = fp.part.train & (fp.ctx.moving > 0)
        return Leftover.of(residual, read, self.designs[0].columns.values)

    def score(self, opt: Option) -> Trial:
        """``opt`` added to the chosen options, fitted on training, scored held out."""
        return self.score_all([opt])[0]

    def score_all(self, opts: Sequence[Option]) -> list[Trial]:
        """:meth:`score` of each of ``opts``, the additive ones in one batch
        (:meth:`~.design.GramDesign.trials`)."""
        scored: dict[int, tuple[list[Columns], tuple[FloatArray, FloatArray]]] = {}
        batch: list[tuple[Option, list[Columns]]] = []
        additive = [o for o in opts if not o.is_filter]
        for i, opt in enumerate(additive):
            # a batch's columns at a time (a grid's all at once: 300 MB)
            batch.append((opt, self.extra(opt)))
            if sum(e[0].lower.size for _, e in batch) >= BATCH_COLUMNS or i + 1 == len(additive):
                results = self.gram.trials([e for _, e in batch])
                scored |= {id(o): (e, r) for (o, e), r in zip(batch, results, strict=True)}
                batch = []
        out = []
        for opt in opts:
            if opt.is_filter:
                theta, held = self._filter_trial(opt)
                out.append(Trial(opt, rms(held), theta, held, lambda: self._all_held))
                continue
            extra, (theta, held) = scored[id(opt)]

            def support(opt: Option = opt, extra: list[Columns] = extra) -> BoolArray:
                pairs = zip(extra, self.parts, strict=True)
                return np.concatenate(
                    [where_acting(opt.acting(fp, e)[fp.part.held], self.rules) for e, fp in pairs]
                )

            out.append(Trial(opt, rms(held), theta, held, support))
        return out

    @functools.cached_property
    def _unfiltered(self) -> list[FloatArray]:
        """Each part's design before the chosen filters (made once for the filter
        trials)."""
        return [
            Columns.join([fp.base] + [o.columns(fp) for o in self.chosen if not o.is_filter]).values
            for fp in self.parts
        ]

    def _filtered(self, opt: Option, index: int) -> FloatArray:
        """Part ``index``'s design through the chosen filters and the filter ``opt``
        (each filter is linear and acts on every column alike: the design of
        :func:`design` with ``opt`` chosen last)."""
        return through([*self.filters, opt], self._unfiltered[index],
                       self.parts[index].ctx.sample_time_s)  # fmt: skip

    def _filter_trial(self, opt: Option) -> tuple[FloatArray, FloatArray]:
        """Coefficients and held-out residual of the design with the filter ``opt`` added,
        fitted on the training rows (:meth:`~.design.GramDesign.refitted`)."""
        return self.gram.refitted([self._filtered(opt, i) for i in range(len(self.parts))])

    def extra(self, opt: Option) -> list[Columns]:
        """The additive ``opt``'s columns on each part, through the chosen filters (the
        last ``COLUMNS_KEPT`` options' kept: a shape is scored, then judged)."""
        key = (opt.effect.name, *sorted(opt.shape.items()))
        if key not in self._columns:
            if len(self._columns) >= COLUMNS_KEPT:
                del self._columns[next(iter(self._columns))]
            self._columns[key] = [opt.columns(fp, self.filters) for fp in self.parts]
        return self._columns[key]

    def whole_rms(self, opt: Option) -> float:
        """The RMS over every row (training and held out) of the design with the
        additive ``opt`` added, fitted on every row: the cost that places the shape of
        an effect at a few events (a dwell gain at a few starts) on all of them, before
        it is judged on each by a fit without it (:meth:`left_out`)."""
        if self._whole is None:
            self._whole = GramDesign(every_row(self.designs))
        return self._whole.trial_train_rms(self.extra(opt))[1]

    def left_out(self, trial: Trial) -> tuple[FloatArray, FloatArray]:
        """Residuals without and with ``trial``'s option at every row where it acts
        (training and held out, every part, in time order), each event's from the design
        fitted on the training rows without it (:meth:`~.design.GramDesign.left_out`;
        an event: rows where it acts less than ``event_gap_s`` apart). An effect at a
        few events (a dwell gain at a few starts) is judged on all of them, none by a fit
        that saw it; the held-out rows alone may hold none of them."""
        extra = self.extra(trial.option)
        return self.gram.left_out(extra, self.events(trial), self.rules.left_out_folds)

    def events(self, trial: Trial) -> list[list[IntArray]]:
        """The rows (each part's, in time order) where ``trial``'s option acts, in events:
        rows less than ``event_gap_s`` apart are one."""
        events = []
        for e, fp in zip(self.extra(trial.option), self.parts, strict=True):
            gap = max(1, round(self.rules.event_gap_s / max(fp.ctx.sample_time_s, 1e-12)))
            events.append(runs(where_acting(trial.option.acting(fp, e), self.rules), gap))
        return events

    def told_apart(self, opt: Option) -> BoolArray | None:
        """The held-out rows (every part's, in order) whose motion can tell ``opt``'s
        effect from the others (:meth:`~gms_comp.measured.policies.Policy.told_apart`),
        or None: every row."""
        masks = opt.policy.told_apart([fp.ctx for fp in self.parts])
        if masks is None:
            return None
        return np.concatenate([m[fp.part.held] for m, fp in zip(masks, self.parts, strict=True)])

    def change(self, trial: Trial) -> FloatArray:
        """How much ``trial`` changes the model force on the main part."""
        if trial.option.is_filter:
            return self._filtered(trial.option, 0) @ trial.theta - self.model()
        m = self.theta.size
        extra = self.extra(trial.option)[0].values
        base = self.designs[0].columns.values
        return base @ trial.theta[:m] + extra @ trial.theta[m:] - self.model()


def base_gram(parts: Sequence[FittedPart], chosen: Sequence[Option] = ()) -> GramDesign:
    """The training Gram matrix of the parts' base columns alone (the GMS's: the same
    while the parts' GMS force is refitted), through ``chosen``'s filters (for
    :func:`fit_on` with the same filters)."""
    return GramDesign(design(parts, [o for o in chosen if o.is_filter]))


def fit_on(
    base: GramDesign, parts: Sequence[FittedPart], chosen: Sequence[Option]
) -> tuple[FloatArray, float]:
    """Coefficients and training RMS of the design of ``chosen`` on ``parts``, whose
    base columns through ``chosen``'s filters ``base`` holds (:func:`base_gram`): the
    additive options' columns added to its Gram matrix, not the whole design built
    (and filtered) again for every trial of the refit's level search."""
    filters = [o for o in chosen if o.is_filter]
    additive = [o for o in chosen if not o.is_filter]
    if not additive:
        theta = base.fit()
        return theta, base.train_rms(theta)
    extra = [Columns.join([o.columns(fp, filters) for o in additive]) for fp in parts]
    return base.trial_train_rms(extra)


def acts_locally(trial: Trial, rules: SelectionConfig) -> bool:
    """Whether ``trial``'s option acts on less than ``local_share`` of the held-out rows."""
    return bool(np.count_nonzero(trial.support) < rules.local_share * trial.support.size)


def best_held_out(m: int, trials: Sequence[Trial], rules: SelectionConfig) -> Trial:
    """The trial that holds out best (``m``: the design's columns before the trial's);
    where that one's effect was fitted at zero (the design as it was) and acts on many
    rows, the best of those fitted above zero that act locally, if one does: the held-out
    rows may hold none of its events (a fall at a trace's two fast moves, mostly trained
    on), and it is then judged at its events."""
    best = min(trials, key=lambda t: t.heldout_rms_N)
    if best.option.is_filter or np.any(best.theta[m:]) or acts_locally(best, rules):
        return best
    fitted = [t for t in trials if np.any(t.theta[m:]) and acts_locally(t, rules)]
    return min(fitted, key=lambda t: t.heldout_rms_N) if fitted else best


def where_acting(values: FloatArray, rules: SelectionConfig) -> BoolArray:
    """The rows where design columns ``values`` act, each column scaled to its peak: the
    fewest rows holding ``support_energy`` of their energy, of those the ones at least
    ``support_level`` of the peak (a raised element's tail through a standstill holds a
    few per cent of its stretch for thousands of rows: not where it acts)."""
    acting = np.zeros(values.shape[0], dtype=bool)
    if values.shape[0] == 0:  # a part without held-out rows (the training trace)
        return acting
    size = np.max(np.abs(values), axis=0)
    energy = np.sum((values / np.where(size > 0, size, np.inf)) ** 2, axis=1)
    total = float(np.sum(energy))
    if total == 0.0:
        return acting
    least = _top_share(energy, rules.support_energy * total)
    if least is not None:
        return (energy >= least) & (energy >= rules.support_level**2)
    order = np.argsort(energy)[::-1]
    count = int(np.searchsorted(np.cumsum(energy[order]), rules.support_energy * total)) + 1
    acting[order[:count]] = True
    return acting & (energy >= rules.support_level**2)


def _top_share(energy: FloatArray, share: float) -> float | None:
    """The least energy of the fewest rows (largest first) whose energies add up to
    ``share``, from the sorted values of the rows with any; None where rows of that
    energy also fall just outside (ties: which of them are in is the argsort's order)."""
    values = np.sort(energy[energy > 0.0])[::-1]
    count = int(np.searchsorted(np.cumsum(values), share)) + 1
    if count > values.size:
        return None
    least = float(values[count - 1])
    return None if count < values.size and values[count] == least else least


def effect_of(
    opt: Option, chosen: Sequence[Option], theta: FloatArray, base_width: int,
    widths: Sequence[int],
) -> fx.Effect:  # fmt: skip
    """The effect with the coefficients ``theta`` holds for ``opt`` in the design of
    ``chosen`` (``widths``: the column count of each chosen option, 0 for a filter)."""
    if opt.is_filter:
        return opt.filter_effect()
    start = base_width
    for other, width in zip(chosen, widths, strict=True):
        if other is opt:
            return opt.effect.from_coefficients(theta[start : start + width], opt.shape)
        start += width
    raise AssertionError("option not in the design")


def widths(parts: Sequence[FittedPart], chosen: Sequence[Option]) -> list[int]:
    """The column count of each chosen option on the main part (0 for a filter)."""
    return [0 if o.is_filter else o.columns(parts[0]).values.shape[1] for o in chosen]


def describe_trials(trials: Sequence[Trial], baseline_rms_N: float) -> list[dict[str, object]]:
    """The best trial of each effect as JSON (effect, shape, held-out RMS, gain)."""
    return [
        {
            "effect": t.option.effect.name,
            "shape": dict(t.option.shape),
            "heldout_rms_N": t.heldout_rms_N,
            "gain": 1.0 - t.heldout_rms_N / baseline_rms_N if baseline_rms_N else 0.0,
        }
        for t in sorted(trials, key=lambda t: t.heldout_rms_N)
    ]
