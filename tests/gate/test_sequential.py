"""The group-sequential boundaries: the Lan-DeMets O'Brien-Fleming spending function, its
boundaries against published and exact values, and the false-alarm rate and power they give,
checked by simulating the looks."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.stats import multivariate_normal, norm

from slipbench.gate.sequential import (
    Boundaries,
    boundaries,
    crossing,
    detectable_drift,
    fractions_of,
    power,
    spending,
)


def test_spending_is_the_formula_and_spends_alpha_at_the_budget():
    t = np.array([0.1, 0.25, 0.5, 1.0])
    expected = 2 - 2 * norm.cdf(norm.ppf(1 - 0.025 / 2) / np.sqrt(t))
    np.testing.assert_allclose(spending(t, 0.025), expected, atol=1e-15)
    assert spending([1.0], 0.025)[0] == pytest.approx(0.025)
    assert np.all(np.diff(spending(np.linspace(0.2, 1, 20), 0.05)) > 0)


@pytest.mark.parametrize("bad", [[0.0, 1.0], [0.5, 1.2], [-0.1]])
def test_spending_refuses_fractions_outside_0_1(bad):
    with pytest.raises(ValueError, match="information fractions"):
        spending(bad, 0.025)


def test_five_equal_looks_match_the_published_boundaries():
    """Jennison and Turnbull's / gsDesign's sfLDOF, one-sided 0.025, five equal looks."""
    b = boundaries([0.2, 0.4, 0.6, 0.8, 1.0], 0.025)
    np.testing.assert_allclose(b.z, [4.8769, 3.3569, 2.6803, 2.2898, 2.0310], atol=2e-4)
    assert b.spent[-1] == pytest.approx(0.025)


def test_one_look_is_the_fixed_design():
    b = boundaries([1.0], 0.025)
    assert b.z[0] == pytest.approx(norm.ppf(0.975))
    assert b.nominal[0] == pytest.approx(0.025)
    assert detectable_drift(b, 0.8) == pytest.approx(norm.ppf(0.975) + norm.ppf(0.8), abs=1e-6)


def test_the_second_look_equals_the_exact_bivariate_normal_one():
    """Two looks at t = 1/3 and 1 (3 seeds, then 9): the second critical value solves the
    bivariate normal equation exactly (correlation sqrt(t1 / t2))."""
    t, alpha = [1 / 3, 1.0], 0.025
    b = boundaries(t, alpha)
    spent = spending(t, alpha)
    r = np.sqrt(t[0] / t[1])
    mvn = multivariate_normal(mean=[0, 0], cov=[[1, r], [r, 1]])

    def excess(c2):
        return norm.cdf(b.z[0]) - mvn.cdf([b.z[0], c2]) - (spent[1] - spent[0])

    assert b.z[1] == pytest.approx(brentq(excess, 1, 5, xtol=1e-10), abs=1e-5)


def _simulated(fractions, drift, n=400_000, seed=0):
    """Cumulative z-statistics of ``n`` Brownian paths with ``drift`` at the looks."""
    rng = np.random.default_rng(seed)
    t = np.asarray(fractions)
    steps = rng.standard_normal((n, len(t))) * np.sqrt(np.diff(t, prepend=0.0))
    score = np.cumsum(steps, axis=1) + drift * t
    return score / np.sqrt(t)


def _first_crossings(z, bounds: Boundaries):
    crossed = z >= np.asarray(bounds.z)
    first = np.where(crossed.any(axis=1), crossed.argmax(axis=1), -1)
    return np.array([(first == k).mean() for k in range(bounds.looks)])


@pytest.mark.parametrize("fractions", [[1 / 3, 2 / 3, 1.0], [0.3, 0.5, 0.7, 1.0]])
def test_simulated_looks_hold_the_false_alarm_rate(fractions):
    """Under no change, paths that cross some look's boundary: alpha in all, and at each look
    what the spending function allots it; looking three times at the fixed design's 1.96 would
    not hold it."""
    alpha = 0.025
    b = boundaries(fractions, alpha)
    z = _simulated(fractions, 0.0)
    per_look = _first_crossings(z, b)
    se = np.sqrt(alpha * (1 - alpha) / len(z))
    assert per_look.sum() == pytest.approx(alpha, abs=4 * se)
    np.testing.assert_allclose(per_look, np.diff(b.spent, prepend=0.0), atol=4 * se)
    np.testing.assert_allclose(crossing(b), np.diff(b.spent, prepend=0.0), atol=1e-7)
    naive = (z >= norm.ppf(1 - alpha)).any(axis=1).mean()
    assert naive > 1.8 * alpha


def test_simulated_power_matches_the_integration_and_the_detectable_drift():
    fractions = [1 / 3, 2 / 3, 1.0]
    b = boundaries(fractions, 0.025 / 6)
    drift = detectable_drift(b, 0.8)
    z = _simulated(fractions, drift, seed=1)
    assert _first_crossings(z, b).sum() == pytest.approx(0.8, abs=0.004)
    assert power(b, drift) == pytest.approx(0.8, abs=1e-6)
    # spending little early keeps the price of looking small: within 3 % of the fixed design's
    fixed = norm.ppf(1 - 0.025 / 6) + norm.ppf(0.8)
    assert fixed < drift < 1.03 * fixed


def test_nominal_levels_fall_early_and_end_near_alpha():
    b = boundaries([0.25, 0.5, 0.75, 1.0], 0.025)
    assert list(b.nominal) == sorted(b.nominal)
    assert b.nominal[0] < 1e-4
    assert 0.02 < b.nominal[-1] < 0.025


def test_fractions_of_looks_in_seeds():
    assert fractions_of([3, 6, 9], 9) == pytest.approx([1 / 3, 2 / 3, 1.0])
    for bad in ([3, 12], [], [0, 3]):
        with pytest.raises(ValueError, match="budget"):
            fractions_of(bad, 9)
    with pytest.raises(ValueError, match="increase"):
        boundaries([0.5, 0.5], 0.025)
