"""The ``mover`` interval method (logit t with the replicates' own logit spread for figures;
MOVER over the level and the contrast of a change) and ``replicate-logit`` (its figures of one
seed, else the default): their mechanics. Their coverage is measured in docs/studies/coverage.md
(``benchmarks/bench_coverage.py --method mover``, ``--method replicate-logit``)."""

from __future__ import annotations

import numpy as np
import pytest
from benchmod import load
from studies.intervals import method as study

from slipbench.stats.metrics import FIGURES, Predictions, over_seeds

bench = load("bench_coverage")


@pytest.mark.parametrize("scenario", ["heavy", "seeds", "ranks"])
def test_bounds_are_finite_and_hold_the_estimate(scenario):
    base, cand = bench.dataset(np.random.default_rng(3), 10, scenario)
    for cand_side, prefix, lo_bound in ((None, "", 0.0), (cand, "d_", -1.0)):
        got = over_seeds(base, cand_side, seed=1, method=study("mover"))
        old = over_seeds(base, cand_side, seed=1)
        for f in FIGURES:
            est, lo, hi = (got[f"{prefix}{f}{s}"] for s in ("", "_lo", "_hi"))
            assert np.isfinite([est, lo, hi]).all(), (scenario, prefix + f)
            assert lo_bound <= lo <= est <= hi <= 1.0, (scenario, prefix + f, lo, est, hi)
            # the estimate and its bootstrap standard error are the default's
            assert est == old[f"{prefix}{f}"] and got[f"{prefix}{f}_se"] == old[f"{prefix}{f}_se"]


def _near_the_bound(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """20 non-slip trials of which two fail often; a candidate that fails less on every trial."""
    rng = np.random.default_rng(seed)
    sizes = rng.integers(20, 80, 40)
    groups = np.repeat(np.arange(40), sizes)
    y = groups < 20
    p_fail = np.where(np.isin(groups, [20, 21]), 0.5, 0.03)
    u = rng.random(len(y))
    base = np.where(y, rng.random(len(y)) < 0.8, u < p_fail)
    cand = np.where(y, base, u < p_fail / 2)
    return y, base, cand, groups


def test_a_rate_near_its_bound_reaches_further_towards_chance():
    """The TN rate near 1: the interval's low side reaches further than the default's (the
    replicates' logits spread more than the delta method says), its high side stays below 1."""
    y, base, _, groups = _near_the_bound(0)
    p = [Predictions(y, base, groups, base + 0.1 * np.random.default_rng(1).random(len(y)))]
    old, new = (
        over_seeds(p, seed=2, method="satterthwaite"),
        over_seeds(p, seed=2, method=study("mover")),
    )
    assert new["tn_rate_lo"] < old["tn_rate_lo"] - 0.005
    assert old["tn_rate_hi"] <= new["tn_rate_hi"] < 1.0


def test_a_change_near_the_bound_reaches_further_away_from_it():
    """Both TN rates near 1, the candidate's higher: the level may be lower than it looks, and
    there the same contrast is a larger change, so the high side reaches further."""
    y, base, cand, groups = _near_the_bound(4)
    sides = [Predictions(y, base, groups)], [Predictions(y, cand, groups)]
    old = over_seeds(*sides, seed=3, figures=("tn_rate",), method="satterthwaite")
    new = over_seeds(*sides, seed=3, figures=("tn_rate",), method=study("mover"))
    assert new["d_tn_rate"] == old["d_tn_rate"] > 0
    assert new["d_tn_rate_hi"] > old["d_tn_rate_hi"]


def test_identical_sides_give_a_change_of_zero_width_and_no_spread_the_default():
    groups = np.repeat(np.arange(8), 5)
    y = groups < 4
    rng = np.random.default_rng(0)
    pred = y ^ (rng.random(40) < 0.2)
    one = [Predictions(y, pred, groups)]
    same = over_seeds(one, [Predictions(y, pred.copy(), groups)], seed=0, method=study("mover"))
    assert same["d_accuracy_lo"] == same["d_accuracy_hi"] == 0.0
    perfect = [Predictions(y, y.copy(), groups, y + 0.1 * groups)]
    assert over_seeds(perfect, seed=0, method=study("mover")) == over_seeds(perfect, seed=0)


def test_it_is_deterministic_given_the_seed():
    base, cand = bench.dataset(np.random.default_rng(4), 10, "ranks")
    assert over_seeds(base, cand, seed=5, method=study("mover")) == over_seeds(
        base, cand, seed=5, method=study("mover")
    )


@pytest.mark.parametrize("scenario", ["normal", "seeds"])
def test_scale_choice_is_the_default_with_replicate_logit_figures(scenario):
    """The default method: figures as ``replicate-logit`` (of one seed, ``mover``'s; over several
    never narrower than ``satterthwaite``, with the same estimate and df); a change as
    ``satterthwaite`` or ``mover``, whichever scale its replicates say is steadier."""
    base, cand = bench.dataset(np.random.default_rng(6), 10, scenario)
    old = (
        over_seeds(base, seed=2, method="satterthwaite"),
        over_seeds(base, cand, seed=2, method="satterthwaite"),
    )
    got = over_seeds(base, seed=2), over_seeds(base, cand, seed=2)
    assert got == (
        over_seeds(base, seed=2, method="scale-choice"),
        over_seeds(base, cand, seed=2, method="scale-choice"),
    )
    assert got[0] == over_seeds(base, seed=2, method=study("replicate-logit"))
    # several seeds per side: the seed terms of satterthwaite (MOVER failed a null study there)
    assert got[1] in (old[1], over_seeds(base, cand, seed=2, method=study("mover")))
    assert scenario != "seeds" or got[1] == old[1]
    if scenario == "normal":
        assert got[0] == over_seeds(base, seed=2, method=study("mover"))
    assert got[0] != old[0]
    for name in FIGURES:
        assert got[0][name] == old[0][name]
        assert got[0][f"{name}_lo"] <= old[0][f"{name}_lo"] + 1e-12, name
        assert got[0][f"{name}_hi"] >= old[0][f"{name}_hi"] - 1e-12, name


def _two_sides(kind: str, seed: int) -> tuple[list[Predictions], list[Predictions]]:
    """30 + 30 trials. ``odds``: the candidate divides every non-slip trial's odds of a false
    alarm by 6 (a constant change on the logit scale); ``shift``: every tenth trial fails both
    sides alike, elsewhere the candidate halves a small error rate (steady on the rate's scale)."""
    rng = np.random.default_rng(seed)
    sizes = rng.integers(20, 80, 60)
    groups = np.repeat(np.arange(60), sizes)
    y = groups < 30
    if kind == "odds":
        p = rng.uniform(0.02, 0.6, 60)
        q = p / 6 / (1 - p + p / 6)
    else:
        bad = np.arange(60) % 10 == 0
        p, q = np.where(bad, 0.9, 0.08), np.where(bad, 0.9, 0.04)
    u = rng.random(len(y))
    base, cand = y | (u < p[groups]), y | (u < q[groups])
    return [Predictions(y, base, groups)], [Predictions(y, cand, groups)]


@pytest.mark.parametrize(("kind", "like"), [("odds", "mover"), ("shift", "satterthwaite")])
def test_scale_choice_takes_the_scale_on_which_the_change_is_steady(kind, like):
    """``scale-choice``: MOVER on the logit scale where the candidate changes the odds alike on
    every trial, the rate's own scale where failing trials move both sides alike."""
    for seed in range(3):
        sides = _two_sides(kind, seed)
        got = over_seeds(*sides, seed=1, method="scale-choice", figures=("tn_rate",))
        ref = over_seeds(*sides, seed=1, method=study(like), figures=("tn_rate",))
        assert (got["d_tn_rate_lo"], got["d_tn_rate_hi"]) == (
            ref["d_tn_rate_lo"],
            ref["d_tn_rate_hi"],
        ), (kind, seed)
