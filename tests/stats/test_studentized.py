"""The ``studentized`` interval method (bootstrap-t united with the ``satterthwaite`` interval): its
mechanics (fast) and its coverage in the three scenarios of ``benchmarks/bench_coverage.py``
at low replications (slow). The study's table is in docs/studies/coverage.md."""

from __future__ import annotations

import numpy as np
import pytest
from benchmod import load
from studies.intervals import method as study

from slipbench.stats.metrics import FIGURES, Predictions, over_seeds

bench = load("bench_coverage")


def _bounds(result: dict, name: str) -> tuple[float, float, float]:
    return result[name], result[f"{name}_lo"], result[f"{name}_hi"]


@pytest.mark.parametrize("scenario", ["heavy", "seeds"])
def test_bounds_are_finite_hold_the_estimate_and_the_default_interval(scenario):
    base, cand = bench.dataset(np.random.default_rng(3), 10, scenario)
    for cand_side, prefix, lo_bound in ((None, "", 0.0), (cand, "d_", -1.0)):
        old = over_seeds(base, cand_side, seed=1, method="satterthwaite")
        new = over_seeds(base, cand_side, seed=1, method=study("studentized"))
        for f in FIGURES:
            est, lo, hi = _bounds(new, prefix + f)
            _, old_lo, old_hi = _bounds(old, prefix + f)
            assert np.isfinite([est, lo, hi]).all(), (scenario, prefix + f)
            assert lo_bound <= lo <= est <= hi <= 1.0, (scenario, prefix + f, lo, est, hi)
            # the union: never narrower than the default on either side
            assert lo <= old_lo + 1e-12 and hi >= old_hi - 1e-12, (scenario, prefix + f)
            assert new[f"{prefix}{f}_se"] == old[f"{prefix}{f}_se"]


def test_a_skewed_rate_widens_its_low_side_only():
    """Non-slip trials mostly perfect, one bad: the TN rate's low side reaches further than the
    default's, its high side stays."""
    rng = np.random.default_rng(0)
    sizes = rng.integers(5, 60, 24)
    groups = np.repeat(np.arange(24), sizes)
    y = groups < 12
    pred = y.copy()
    bad = groups == 12  # a non-slip trial that fails wholesale
    pred[bad] = True
    pred[(groups == 13) & (rng.random(len(y)) < 0.2)] = True
    pred[y & (rng.random(len(y)) < 0.2)] = False
    p = [Predictions(y, pred, groups, pred + rng.normal(0, 0.5, len(y)))]
    old = over_seeds(p, seed=2, method="satterthwaite")
    new = over_seeds(p, seed=2, method=study("studentized"))
    assert new["tn_rate_lo"] < old["tn_rate_lo"] - 0.01
    assert new["tn_rate_hi"] == pytest.approx(old["tn_rate_hi"])


def test_equals_the_default_where_there_is_no_spread_or_no_estimate():
    """Every trial perfect (no spread: Clopper-Pearson) and a class of one trial (not estimable:
    the whole range) give exactly the default interval."""
    groups = np.repeat(np.arange(8), 5)
    y = groups < 4
    perfect = [Predictions(y, y.copy(), groups, y + 0.1 * groups)]
    one_class = [Predictions(groups < 7, np.ones(40, bool), groups, np.arange(40.0))]
    for parts in (perfect, one_class):
        assert over_seeds(parts, seed=0, method=study("studentized")) == over_seeds(
            parts, seed=0, method="satterthwaite"
        )


def test_it_is_deterministic_given_the_seed():
    base, _ = bench.dataset(np.random.default_rng(4), 10, "normal")
    a = over_seeds(base, seed=5, method=study("studentized"))
    assert a == over_seeds(base, seed=5, method=study("studentized"))


@pytest.mark.slow
def test_studentized_covers_in_every_scenario_at_low_reps():
    """40 replications at 10 and 20 trials per class, pooled per scenario (80 test sets: two
    standard errors about 0.05); the band 0.88-1.0 (the change in AUROC overcovers, as the
    default does)."""
    table = bench.study(40, ("normal", "heavy", "seeds"), sizes=(10, 20), method="studentized")
    pooled = table.groupby("scenario")[list(bench.NAMES)].mean()
    outside = {
        (s, k): round(v, 3) for s, row in pooled.iterrows() for k, v in row.items() if v < 0.88
    }
    assert not outside, outside
