"""Statistics: interval coverage by simulation, AUROC against scikit-learn, paired comparison."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.metrics import balanced_accuracy_score, roc_auc_score

from slipbench.metrics import (
    auroc_ci, classification_figures, cluster_bootstrap_ci, holm, paired_comparison, wilson_ci,
)

TRUE_ACCURACY = 0.8


def simulated_datasets(n_datasets: int, n_recordings: int, seed: int):
    """Hit counts of datasets whose windows are correlated within a recording.

    Each recording has its own accuracy p_c ~ Beta(8, 2) (mean 0.8, intra-recording
    correlation 1 / 11) and 10-30 windows; a window is correct with probability p_c. The
    accuracy the intervals must cover is the mean, 0.8.
    """
    rng = np.random.default_rng(seed)
    sizes = rng.integers(10, 31, size=(n_datasets, n_recordings))
    hits = rng.binomial(sizes, rng.beta(8, 2, size=(n_datasets, n_recordings)))
    return sizes, hits


def windows_of(sizes: np.ndarray, hits: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Expand per-recording counts into per-window (hit, recording) arrays."""
    groups = np.repeat(np.arange(len(sizes)), sizes)
    first = np.repeat(np.cumsum(sizes) - sizes, sizes)
    # the first hits[c] windows of recording c are correct, the rest not
    correct = (np.arange(sizes.sum()) - first) < np.repeat(hits, sizes)
    return correct.astype(float), groups


def test_cluster_bootstrap_covers_at_nominal_rate_and_wilson_undercovers():
    sizes, hits = simulated_datasets(400, 40, seed=5)
    cover_bootstrap = cover_wilson = 0
    for d in range(len(sizes)):
        correct, groups = windows_of(sizes[d], hits[d])
        lo, hi = cluster_bootstrap_ci(correct, groups, seed=d)
        cover_bootstrap += lo <= TRUE_ACCURACY <= hi
        lo, hi = wilson_ci(int(correct.sum()), len(correct))
        cover_wilson += lo <= TRUE_ACCURACY <= hi
    # 95 % intervals: the cluster bootstrap covers at close to 95 % (measured: 378/400)...
    assert 0.92 * 400 <= cover_bootstrap <= 0.98 * 400, cover_bootstrap
    # ...while the window-level Wilson interval, which treats correlated windows as
    # independent, is far too narrow (measured: 290/400).
    assert cover_wilson < 0.85 * 400, cover_wilson


def test_wilson_matches_independent_windows():
    """With independent windows the Wilson interval is right too: it is not wrong, only misapplied."""
    rng = np.random.default_rng(1)
    cover = sum(lo <= 0.8 <= hi for lo, hi in (wilson_ci(int(rng.binomial(500, 0.8)), 500) for _ in range(400)))
    assert 0.92 * 400 <= cover <= 0.98 * 400


def test_auroc_equals_scikit_learn_with_ties():
    rng = np.random.default_rng(0)
    y = rng.random(3000) < 0.5
    scores = np.round(rng.random(3000) + 0.4 * y, 1)  # coarse: many ties
    groups = rng.integers(0, 50, 3000)
    auc, lo, hi = auroc_ci(y, scores, groups, seed=0)
    assert auc == pytest.approx(roc_auc_score(y, scores), abs=1e-12)
    assert lo < auc < hi


def test_classification_figures():
    rng = np.random.default_rng(2)
    y = rng.random(2000) < 0.5
    scores = np.clip(0.5 + 0.3 * (y - 0.5) + rng.normal(0, 0.3, 2000), 0, 1)
    pred = scores >= 0.5
    groups = rng.integers(0, 40, 2000)
    f = classification_figures(y, pred, groups, seed=0, scores=scores)
    assert f["tp"] + f["tn"] + f["fp"] + f["fn"] == 2000
    assert f["accuracy"] == pytest.approx((pred == y).mean())
    assert f["balanced_accuracy"] == pytest.approx(balanced_accuracy_score(y, pred))
    assert f["auroc"] == pytest.approx(roc_auc_score(y, scores))
    for name in ("accuracy", "tp_rate", "tn_rate", "balanced_accuracy", "auroc"):
        assert f[f"{name}_lo"] <= f[name] <= f[f"{name}_hi"], name
    assert f == classification_figures(y, pred, groups, seed=0, scores=scores)  # deterministic
    assert np.isnan(classification_figures(y, pred, groups, seed=0)["auroc"])


def test_paired_comparison_of_identical_predictions_is_no_change():
    rng = np.random.default_rng(3)
    y = rng.random(1000) < 0.5
    pred = rng.random(1000) < 0.5
    out = paired_comparison(y, pred, pred, rng.integers(0, 30, 1000), seed=0)
    assert out["mcnemar_p"] == 1.0 and out["n_discordant"] == 0
    assert out["d_accuracy"] == out["d_accuracy_lo"] == out["d_accuracy_hi"] == 0.0


def test_paired_comparison_finds_a_degraded_detector():
    rng = np.random.default_rng(4)
    y = rng.random(4000) < 0.5
    base = np.where(rng.random(4000) < 0.9, y, ~y)
    cand = np.where(rng.random(4000) < 0.3, ~base, base)  # flips 30 % of the base's answers
    out = paired_comparison(y, base, cand, rng.integers(0, 80, 4000), seed=0)
    assert out["mcnemar_p"] < 1e-6
    assert out["d_accuracy_hi"] < 0 and out["d_accuracy_lo"] < out["d_accuracy"] < out["d_accuracy_hi"]
    assert out["d_accuracy"] == pytest.approx((cand == y).mean() - (base == y).mean())


def test_holm():
    adjusted = holm([0.01, 0.04, np.nan, 0.03])
    np.testing.assert_allclose(adjusted[[0, 1, 3]], [0.03, 0.06, 0.06])
    assert np.isnan(adjusted[2])
