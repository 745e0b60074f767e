"""The study of the findings' contrast intervals (``benchmarks/bench_findings_contrast.py``):
its simulation against its closed-form truth (fast), and the study at few replications (slow).
The full study's table is in docs/coverage.md."""

from __future__ import annotations

import numpy as np
import pytest
from benchmod import load

bench = load("bench_findings_contrast")


@pytest.mark.slow  # four sensors of 150 trials per class: about 15 s
def test_the_simulation_matches_its_truth():
    """Many trials and no retraining noise: every contrast, averaged over four simulated
    sensors of 150 trials per class, lands on its closed form (the TP - TN gap compares
    different trials, so it varies most: about 2.5 points per sensor)."""
    rng = np.random.default_rng(3)
    runs = [bench.contrasts(bench.rows(rng, 150, "test", r)) for r in range(4)]
    true = bench.truth("test")
    assert set(runs[0]) == set(true)
    for name in true:
        assert np.mean([run[name].value for run in runs]) == pytest.approx(true[name], abs=2.5)
        assert all(run[name].lo < run[name].value < run[name].hi for run in runs)
    # retraining noise pulls every rate towards one half: the truths shrink with it
    strong = bench.truth("strong-1")
    assert all(abs(strong[k]) < abs(true[k]) for k in ("rise", "gap", "lead"))


def test_three_seeds_give_a_row_per_cell_and_seed():
    rows = bench.rows(np.random.default_rng(0), 10, "seeds-3", 0)
    assert len(rows) == len(bench.FINGERS) * len(bench.LEVELS) * 3
    assert set(rows["seed"]) == {0, 1, 2}
