"""Pure functions from (y_true, y_pred, groups) to figures with confidence intervals."""

from __future__ import annotations

import numpy as np
from scipy.stats import bootstrap

LEVEL = 0.95
N_RESAMPLES = 999


def cluster_bootstrap_ci(
    hits: np.ndarray, groups: np.ndarray, seed: int, level: float = LEVEL, n_resamples: int = N_RESAMPLES
) -> tuple[float, float]:
    """Percentile bootstrap interval of a proportion whose observations come in clusters.

    Windows cut from one recording are correlated, so whole recordings (``groups``) are
    resampled, keeping each one's hit count and window count together (``scipy.stats.bootstrap``
    with paired samples). Returns (nan, nan) when there are fewer than two clusters.
    """
    hits = np.asarray(hits, dtype=float)
    if len(hits) == 0:
        return float("nan"), float("nan")
    _, codes = np.unique(groups, return_inverse=True)
    k = np.bincount(codes, weights=hits)
    n = np.bincount(codes).astype(float)
    if len(n) < 2:
        return float("nan"), float("nan")
    if np.ptp(k / n) == 0:  # every cluster scores the same: no spread to resample
        p = float(k.sum() / n.sum())
        return p, p
    res = bootstrap(
        (k, n), lambda k, n, axis=-1: k.sum(axis=axis) / n.sum(axis=axis), paired=True, vectorized=True,
        n_resamples=n_resamples, confidence_level=level, method="percentile", rng=np.random.default_rng(seed),
    )
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


def classification_figures(y_true: np.ndarray, y_pred: np.ndarray, groups: np.ndarray, seed: int) -> dict[str, float]:
    """Counts, accuracy, TP rate (slip caught) and TN rate (non-slip passed), with 95 % intervals."""
    y_true = np.asarray(y_true).astype(bool)
    y_pred = np.asarray(y_pred).astype(bool)
    groups = np.asarray(groups)
    correct = y_true == y_pred
    out: dict[str, float] = {
        "tp": int((y_true & y_pred).sum()), "tn": int((~y_true & ~y_pred).sum()),
        "fp": int((~y_true & y_pred).sum()), "fn": int((y_true & ~y_pred).sum()),
    }
    for name, mask in (("accuracy", slice(None)), ("tp_rate", y_true), ("tn_rate", ~y_true)):
        hits = correct[mask]
        out[name] = float(hits.mean()) if len(hits) else float("nan")
        out[f"{name}_lo"], out[f"{name}_hi"] = cluster_bootstrap_ci(hits, groups[mask], seed)
    return out
