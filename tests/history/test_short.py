"""Short series: the best cut judged on each run's own interval, scaled by the history's
run-to-run spread or replaced by the runs' scatter where that is larger."""

from __future__ import annotations

import numpy as np
import pytest

from slipbench.history.short import FEWEST, OWN, SCATTER, scale, short_change
from slipbench.stats.contrast import SHOWN, from_parts

SE = np.full(5, 0.01)
DF = np.full(5, 30.0)


def test_the_cut_is_where_the_series_moved_and_its_interval_is_the_runs_own():
    value = np.array([0.80, 0.80, 0.80, 0.74, 0.74])
    cut, change = short_change((value, SE, DF), 1.0, 0.99, 0.01)
    assert cut == 3
    assert change.estimate == pytest.approx(-0.06)
    # each run's variance over its side's runs squared, one part a run (no scatter: flat sides)
    parts = [(0.01**2 / 9, 30.0)] * 3 + [(0.01**2 / 4, 30.0)] * 2
    same = from_parts(-0.06, parts, 0.99, 0.01)
    assert (change.lo, change.hi) == pytest.approx((same.lo, same.hi))
    assert change.state == SHOWN and change.noise == (OWN,)
    # the history's scale widens it
    wider = short_change((value, SE, DF), 4.0, 0.99, 0.01)[1]
    assert wider.hi - wider.lo == pytest.approx(2 * (change.hi - change.lo))


def test_the_runs_scatter_counts_where_it_is_larger_than_their_intervals():
    value = np.array([0.80, 0.84, 0.76, 0.70, 0.66])
    cut, change = short_change((value, SE, DF), 1.0, 0.99, 0.01)
    assert change.noise == (SCATTER,)
    assert change.df == pytest.approx(3)  # points - 2
    assert change.state != SHOWN  # the scatter of 4 points a run does not show 12 points


def test_scale_is_the_robust_spread_of_successive_differences_at_least_one():
    rng = np.random.default_rng(0)
    noisy = [(rng.normal(0, 0.03, 5), np.full(5, 0.01)) for _ in range(200)]
    assert scale(noisy) == pytest.approx(9, rel=0.2)
    assert scale([(np.zeros(5), np.full(5, 0.01))] * 3) == 1.0
    assert scale([(np.zeros(2), np.full(2, 0.01))]) == 1.0  # fewer than 3 differences


def test_a_short_series_needs_its_fewest_points():
    with pytest.raises(ValueError, match="3 points"):
        short_change((np.zeros(FEWEST - 1), SE[:2], DF[:2]), 1.0, 0.99, 0.01)
