"""Where an effect on few samples is judged: its peaks, not a long low tail."""

from __future__ import annotations

import numpy as np
from scipy import optimize

from gms_comp.measured.diagnosis.candidates import where_acting
from gms_comp.measured.diagnosis.config import SelectionConfig

RULES = SelectionConfig()


def _peaks_with_tails(tail: float) -> tuple[np.ndarray, np.ndarray]:
    """Ten triangular peaks of height 1 (41 samples each), each followed by a flat tail
    of ``tail`` over 2000 samples (a raised element that never slipped again)."""
    peak = 1.0 - np.abs(np.arange(-20, 21)) / 21.0
    column, in_peak = [], []
    for _ in range(10):
        column += [np.zeros(100), peak, np.full(2000, tail)]
        in_peak += [np.zeros(100, bool), np.ones(peak.size, bool), np.zeros(2000, bool)]
    return np.concatenate(column)[:, None], np.concatenate(in_peak)


def test_a_low_tail_is_not_where_the_effect_acts() -> None:
    values, in_peak = _peaks_with_tails(0.05)
    # the tail holds a good part of the energy: by energy alone it would be in
    tail_share = np.sum(values[~in_peak] ** 2) / np.sum(values**2)
    assert tail_share > 0.15
    acting = where_acting(values, RULES)
    assert not acting[~in_peak].any()
    # the peaks down to a tenth of their height
    assert np.array_equal(acting[in_peak], values[in_peak, 0] >= 0.1)


def test_without_a_tail_the_tops_of_the_peaks() -> None:
    with_tail, in_peak = _peaks_with_tails(0.05)
    without, _ = _peaks_with_tails(0.0)
    acting = where_acting(without, RULES)
    assert not (acting & ~where_acting(with_tail, RULES)).any()  # no more than with the tail
    assert acting[in_peak & (without[:, 0] >= 0.5)].all()


def test_a_broad_column_acts_where_it_holds_most_of_its_energy() -> None:
    # a sine over whole periods holds a share f + sin(pi f) / pi of its energy in the
    # fraction f of the samples where it is largest; 90 % needs f = 0.596
    f = optimize.brentq(lambda f: f + np.sin(np.pi * f) / np.pi - 0.9, 0.0, 1.0)
    values = np.sin(np.linspace(0.0, 200 * np.pi, 20_000, endpoint=False))[:, None]
    share = np.count_nonzero(where_acting(values, RULES)) / values.shape[0]
    assert abs(share - f) < 0.005


def test_no_rows_and_a_zero_column_act_nowhere() -> None:
    assert where_acting(np.zeros((0, 1)), RULES).size == 0
    assert not where_acting(np.zeros((50, 2)), RULES).any()


def _support_by_full_sort(values: np.ndarray) -> np.ndarray:
    """The definition, by a full sort: the fewest rows, largest energy first, holding 90 %
    of the energy (each column scaled to its peak), of those the ones at 10 % of the peak."""
    size = np.max(np.abs(values), axis=0)
    energy = np.sum((values / size) ** 2, axis=1)
    order = np.argsort(energy)[::-1]
    count = int(np.searchsorted(np.cumsum(energy[order]), 0.9 * energy.sum())) + 1
    acting = np.zeros(energy.size, dtype=bool)
    acting[order[:count]] = True
    return acting & (energy >= 0.01)


def test_support_is_the_full_sort_s_including_ties() -> None:
    # the rows are found from the sorted energies of the rows with any; where rows of the
    # least energy taken also fall outside (ties), the full sort's own choice is kept
    rng = np.random.default_rng(3)
    columns = [
        rng.normal(size=(20_000, 1)),
        np.where(rng.random((20_000, 1)) < 0.01, rng.normal(size=(20_000, 1)), 0.0),
        np.round(rng.normal(size=(20_000, 2)), 1),  # many ties
        np.ones((5_000, 1)),  # every row ties
        np.exp(-np.arange(20_000) / 400.0)[:, None] * np.sin(np.arange(20_000))[:, None],
    ]
    for values in columns:
        np.testing.assert_array_equal(where_acting(values, RULES), _support_by_full_sort(values))
