"""The gate's plan: the drop a pooled test flags with 80 % power at the bench's seeds and at its
budget, checked against the gate's own formula and by simulating the looks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import norm

from slipbench.gate import gate
from slipbench.gate.power import (
    MAX_LOOKS,
    Design,
    looks,
    nominal_levels,
    resolution,
    sight,
)


def test_looks_step_by_the_first_and_end_at_the_budget():
    assert looks(3, 12) == [3, 6, 9, 12]
    assert looks(3, 10) == [3, 6, 9, 10]
    assert looks(3, 3) == [3]
    with pytest.raises(ValueError, match="seeds <= budget"):
        Design(4, 3, 6, 0.025)
    with pytest.raises(ValueError, match="tests >= 1"):
        Design(3, 12, 0, 0.025)


def test_one_look_is_the_gates_own_resolution():
    """No budget beyond the seeds: the gate's formula, Bonferroni over the pooled tests."""
    design = Design(3, 3, 6, 0.025)
    assert nominal_levels(design) == [0.025 / 12]
    for df in (4.0, 20.0, math.inf):
        mine = resolution(2.0, df, 3, design.level)
        assert mine == pytest.approx(gate.resolution(2.0 / math.sqrt(3), df, 6, 0.025))
    s = sight(2.0, 20.0, 1.0, design)
    assert s.at_seeds == s.at_budget


def test_a_drop_of_tolerance_plus_x_is_flagged_with_80_percent_power_over_the_looks():
    """Normal changes (infinite df) seen at 3, 6, 9 and 12 seeds, each look flagging at its
    nominal level: a drop of tolerance + X(budget) is flagged by some look at least 80 % of the
    time (the last look alone: 80 %), and a drop of exactly the tolerance at most at the
    test's level over all looks."""
    sd, tol = 1.0, 1.0
    design = Design(3, 12, 6, 0.025)
    s = sight(sd, math.inf, tol, design)
    at = looks(3, 12)
    levels = np.array(nominal_levels(design))
    rng = np.random.default_rng(0)

    def flagged(drop, n=200_000):
        per_seed = drop + sd * rng.standard_normal((n, 12))
        means = np.cumsum(per_seed, axis=1)[:, np.array(at) - 1] / np.array(at)
        z = (means - tol) / (sd / np.sqrt(at))
        return z >= norm.isf(levels)

    hits = flagged(tol + s.at_budget)
    assert hits[:, -1].mean() == pytest.approx(0.8, abs=0.005)
    assert hits.any(axis=1).mean() >= 0.8
    assert flagged(tol).any(axis=1).mean() == pytest.approx(design.level, abs=0.0004)


def test_a_budget_makes_the_first_look_stricter_and_the_last_see_more():
    one = sight(1.0, 30.0, 1.0, Design(3, 3, 6, 0.025))
    seq = sight(1.0, 30.0, 1.0, Design(3, 12, 6, 0.025))
    assert seq.at_seeds > one.at_seeds  # the first look spends little
    assert seq.at_budget < one.at_budget  # four times the seeds
    assert seq.detectable == pytest.approx(seq.tolerance + seq.at_budget)


def test_what_would_decide_an_undecided_test():
    design = Design(3, 12, 6, 0.025)
    s = sight(1.1, 20.0, 1.0, design)
    assert not s.decides and s.budget_needed > 12 and s.budget_needed % 3 == 0
    ok = sight(1.1, 20.0, 1.0, Design(3, s.budget_needed, 6, 0.025))
    short = sight(1.1, 20.0, 1.0, Design(3, s.budget_needed - 3, 6, 0.025))
    assert ok.decides and not short.decides  # the fewest that decide
    assert sight(1.1, 20.0, s.at_budget, design).decides  # the tolerance it names decides
    assert s.data_needed == pytest.approx((s.at_budget / 1.0) ** 2)
    hopeless = sight(100.0, 20.0, 1.0, design)
    assert hopeless.budget_needed == 0  # not within MAX_LOOKS looks
    assert not sight(100.0, 20.0, 1.0, Design(3, 3 * MAX_LOOKS, 6, 0.025)).decides


def test_no_noise_decides_and_unknown_noise_never_does():
    design = Design(3, 12, 6, 0.025)
    quiet = sight(0.0, 20.0, 1.0, design)
    assert quiet.decides and quiet.at_budget == 0 and quiet.budget_needed == 3
    unknown = sight(math.nan, 20.0, 1.0, design)
    assert not unknown.decides and unknown.budget_needed == 0
    assert not sight(1.0, 0.0, 1.0, design).decides  # no degrees of freedom: nothing known
