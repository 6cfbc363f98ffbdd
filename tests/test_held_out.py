"""The diagnosis's held-out split: a third of the blocks, holding fast and slow motion alike."""

from __future__ import annotations

import numpy as np

from gms_comp.measured.diagnosis.prepare import held_out


def test_a_third_of_the_blocks_whole_blocks_only() -> None:
    a = np.random.default_rng(1).normal(size=60_000)
    held = held_out(a, 60)
    block = np.arange(a.size) * 60 // a.size
    assert len(set(block[held])) == 20
    # a block is held out whole or not at all
    assert all(np.all(held[block == b]) or not np.any(held[block == b]) for b in range(60))


def test_few_fast_moves_are_shared_between_the_parts() -> None:
    # three short fast moves in a slow trace, all in blocks a time-order split trains on
    # (blocks 0, 3 and 6 of 60: every third from the second is 1, 4, 7, ...)
    n = 60_000
    a = np.full(n, 1e-3)
    for b in (0, 3, 6):
        a[b * 1000 + 400 : b * 1000 + 600] = 5.0
    held = held_out(a, 60)
    time_order = (np.arange(n) * 60 // n) % 3 == 1
    assert np.sum(a[time_order] ** 2) < 1e-3 * np.sum(a**2)  # what the old split held
    # stratified: the second-fastest block is held out, the other two train
    share = np.sum(a[held] ** 2) / np.sum(a**2)
    assert 0.2 < share < 0.5
    # and the slow blocks split a third / two thirds too
    slow = np.ones(n, dtype=bool)
    for b in (0, 3, 6):
        slow[b * 1000 : (b + 1) * 1000] = False
    assert abs(np.mean(held[slow]) - 1 / 3) < 0.02
