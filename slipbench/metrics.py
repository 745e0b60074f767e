"""Pure functions from (y_true, y_pred or scores, groups) to figures with confidence intervals.

Windows cut from one recording are correlated, so every default interval here is a *cluster*
bootstrap: whole recordings (``groups``) are resampled, never single windows. Window-level
Wilson intervals are offered beside them for the view that treats windows as independent;
``tests/test_metrics.py`` shows by simulation that the first covers at its nominal rate and
the second does not when windows are correlated.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd
from scipy.stats import bootstrap
from statsmodels.stats.contingency_tables import mcnemar
from statsmodels.stats.multitest import multipletests
from statsmodels.stats.proportion import proportion_confint

LEVEL = 0.95
N_RESAMPLES = 999


def _clusters(groups: np.ndarray) -> tuple[np.ndarray, int]:
    _, codes = np.unique(groups, return_inverse=True)
    return codes, int(codes.max()) + 1 if len(codes) else 0


def _bootstrap(
    data: tuple[np.ndarray, ...], statistic: Callable[..., np.ndarray], seed: int, level: float, n_resamples: int,
) -> tuple[float, float]:
    """Percentile interval of ``statistic`` over paired per-cluster arrays (scipy.stats.bootstrap)."""
    res = bootstrap(
        data, statistic, paired=True, vectorized=True, n_resamples=n_resamples, confidence_level=level,
        method="percentile", rng=np.random.default_rng(seed),
    )
    lo, hi = res.confidence_interval
    return float(lo), float(hi)


def cluster_bootstrap_ci(
    hits: np.ndarray, groups: np.ndarray, seed: int, level: float = LEVEL, n_resamples: int = N_RESAMPLES
) -> tuple[float, float]:
    """Percentile bootstrap interval of a proportion whose observations come in clusters.

    Parameters
    ----------
    hits : ndarray of shape (n_windows,)
        1 where the window was classified correctly.
    groups : ndarray of shape (n_windows,)
        The recording each window was cut from.

    Returns
    -------
    (low, high), or (nan, nan) with fewer than two clusters. Whole recordings are resampled,
    each keeping its hit count and window count together.
    """
    hits = np.asarray(hits, dtype=float)
    if len(hits) == 0:
        return float("nan"), float("nan")
    codes, n_clusters = _clusters(np.asarray(groups))
    k = np.bincount(codes, weights=hits, minlength=n_clusters)
    n = np.bincount(codes, minlength=n_clusters).astype(float)
    if n_clusters < 2:
        return float("nan"), float("nan")
    if np.ptp(k / n) == 0:  # every cluster scores the same: no spread to resample
        p = float(k.sum() / n.sum())
        return p, p
    return _bootstrap((k, n), lambda k, n, axis=-1: k.sum(axis=axis) / n.sum(axis=axis), seed, level, n_resamples)


def wilson_ci(hits: int, n: int, level: float = LEVEL) -> tuple[float, float]:
    """Window-level Wilson interval (statsmodels): right only if windows were independent."""
    if n == 0:
        return float("nan"), float("nan")
    lo, hi = proportion_confint(hits, n, alpha=1 - level, method="wilson")
    return float(lo), float(hi)


def balanced_accuracy_ci(
    correct: np.ndarray, y_true: np.ndarray, groups: np.ndarray, seed: int,
    level: float = LEVEL, n_resamples: int = N_RESAMPLES,
) -> tuple[float, float]:
    """Cluster bootstrap interval of (TP rate + TN rate) / 2."""
    codes, n_clusters = _clusters(np.asarray(groups))
    if n_clusters < 2:
        return float("nan"), float("nan")
    pos = np.asarray(y_true, bool)
    correct = np.asarray(correct, float)
    counts = [np.bincount(codes, weights=w, minlength=n_clusters) for w in (correct * pos, pos, correct * ~pos, ~pos)]

    def statistic(kp, np_, kn, nn, axis=-1):
        with np.errstate(invalid="ignore", divide="ignore"):  # a resample may lack one class
            return 0.5 * (kp.sum(axis=axis) / np_.sum(axis=axis) + kn.sum(axis=axis) / nn.sum(axis=axis))

    return _bootstrap(tuple(counts), statistic, seed, level, n_resamples)


def pair_counts(y_true: np.ndarray, scores: np.ndarray, codes: np.ndarray, n_clusters: int) -> np.ndarray:
    """``A[c, d]``: pairs (slip window of recording c, non-slip window of recording d) that the
    scores rank correctly, ties counting one half. Shape (n_clusters, n_clusters)."""
    pos = np.asarray(y_true, bool)
    s_pos, c_pos = scores[pos], codes[pos]
    out = np.zeros((n_clusters, n_clusters))
    for d in np.unique(codes[~pos]):
        neg = np.sort(scores[~pos & (codes == d)])
        below = np.searchsorted(neg, s_pos, "left")
        ties = np.searchsorted(neg, s_pos, "right") - below
        out[:, d] = np.bincount(c_pos, weights=below + 0.5 * ties, minlength=n_clusters)
    return out


def auroc_ci(
    y_true: np.ndarray, scores: np.ndarray, groups: np.ndarray, seed: int,
    level: float = LEVEL, n_resamples: int = N_RESAMPLES,
) -> tuple[float, float, float]:
    """AUROC of ``scores`` with a cluster bootstrap percentile interval.

    Written by hand rather than calling ``sklearn.metrics.roc_auc_score`` per resample: that
    costs about 1 s per cell of 8 000 windows (999 sorts), while the AUROC of a cluster resample
    is a quadratic form in the resampling counts ``w`` over the per-cluster pair counts ``A``,
    ``w @ A @ w / ((w @ n_pos) (w @ n_neg))``, which costs milliseconds. The point estimate
    equals ``roc_auc_score`` (tested).
    """
    y_true = np.asarray(y_true, bool)
    scores = np.asarray(scores, float)
    if y_true.all() or not y_true.any():
        return float("nan"), float("nan"), float("nan")
    codes, n_clusters = _clusters(np.asarray(groups))
    a = pair_counts(y_true, scores, codes, n_clusters)
    n_pos = np.bincount(codes, weights=y_true, minlength=n_clusters)
    n_neg = np.bincount(codes, weights=~y_true, minlength=n_clusters)
    auc = float(a.sum() / (n_pos.sum() * n_neg.sum()))
    if n_clusters < 2:
        return auc, float("nan"), float("nan")
    rng = np.random.default_rng(seed)
    w = rng.multinomial(n_clusters, np.full(n_clusters, 1 / n_clusters), size=n_resamples).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):  # a resample may lack one class
        stats = np.einsum("bc,cd,bd->b", w, a, w) / ((w @ n_pos) * (w @ n_neg))
    stats = stats[np.isfinite(stats)]
    alpha = (1 - level) / 2
    lo, hi = np.quantile(stats, [alpha, 1 - alpha])
    return auc, float(lo), float(hi)


def classification_figures(
    y_true: np.ndarray, y_pred: np.ndarray, groups: np.ndarray, seed: int, scores: np.ndarray | None = None,
) -> dict[str, float]:
    """Every figure of one cell, each with a 95 % interval.

    Parameters
    ----------
    y_true, y_pred : ndarray of shape (n_windows,)
        Labels (1 slip) and hard predictions.
    groups : ndarray of shape (n_windows,)
        The recording of each window: the cluster of the bootstrap.
    seed : int
        Seeds every bootstrap, so figures are reproducible.
    scores : ndarray of shape (n_windows,), optional
        Slip probabilities; gives the AUROC.

    Returns
    -------
    dict
        Counts ``tp, tn, fp, fn``; ``accuracy``, ``tp_rate`` (slip caught), ``tn_rate``
        (non-slip passed), ``balanced_accuracy`` and ``auroc``, each with ``_lo``/``_hi``
        (cluster bootstrap over recordings); and window-level Wilson bounds
        ``<rate>_wilson_lo``/``_hi`` for accuracy, TP and TN rate.
    """
    y_true = np.asarray(y_true).astype(bool)
    y_pred = np.asarray(y_pred).astype(bool)
    groups = np.asarray(groups)
    correct = y_true == y_pred
    out: dict[str, float] = {
        "tp": int((y_true & y_pred).sum()), "tn": int((~y_true & ~y_pred).sum()),
        "fp": int((~y_true & y_pred).sum()), "fn": int((y_true & ~y_pred).sum()),
    }
    for name, mask in (("accuracy", np.ones(len(y_true), bool)), ("tp_rate", y_true), ("tn_rate", ~y_true)):
        hits = correct[mask]
        out[name] = float(hits.mean()) if len(hits) else float("nan")
        out[f"{name}_lo"], out[f"{name}_hi"] = cluster_bootstrap_ci(hits, groups[mask], seed)
        out[f"{name}_wilson_lo"], out[f"{name}_wilson_hi"] = wilson_ci(int(hits.sum()), len(hits))
    out["balanced_accuracy"] = 0.5 * (out["tp_rate"] + out["tn_rate"])
    out["balanced_accuracy_lo"], out["balanced_accuracy_hi"] = balanced_accuracy_ci(correct, y_true, groups, seed)
    if scores is None:
        out["auroc"] = out["auroc_lo"] = out["auroc_hi"] = float("nan")
    else:
        out["auroc"], out["auroc_lo"], out["auroc_hi"] = auroc_ci(y_true, scores, groups, seed)
    return out


# ----------------------------------------------------------------------------- paired comparison
def paired_comparison(
    y_true: np.ndarray, base_pred: np.ndarray, cand_pred: np.ndarray, groups: np.ndarray, seed: int,
    level: float = LEVEL, n_resamples: int = N_RESAMPLES,
) -> dict[str, float]:
    """Two detectors' predictions on the same test windows: McNemar's test and paired cluster
    bootstrap intervals of the change (candidate - base) in accuracy, TP and TN rate.

    Parameters
    ----------
    y_true, base_pred, cand_pred, groups : ndarray of shape (n_windows,)
        Labels, the two hard predictions, and each window's recording (the cluster).

    Returns
    -------
    dict
        ``d_<rate>`` with ``_lo``/``_hi`` for accuracy, tp_rate and tn_rate; ``mcnemar_p``
        (exact binomial test when fewer than 25 windows are discordant, else chi-square with
        continuity correction); ``n_discordant``.
    """
    y_true = np.asarray(y_true, bool)
    hit_b = np.asarray(base_pred, bool) == y_true
    hit_c = np.asarray(cand_pred, bool) == y_true
    b, c = int((hit_b & ~hit_c).sum()), int((~hit_b & hit_c).sum())
    table = [[int((hit_b & hit_c).sum()), b], [c, int((~hit_b & ~hit_c).sum())]]
    out: dict[str, float] = {
        "mcnemar_p": 1.0 if b + c == 0 else float(mcnemar(table, exact=b + c < 25, correction=True).pvalue),
        "n_discordant": b + c,
    }
    codes, n_clusters = _clusters(np.asarray(groups))
    for name, mask in (("accuracy", np.ones(len(y_true), bool)), ("tp_rate", y_true), ("tn_rate", ~y_true)):
        n = mask.sum()
        out[f"d_{name}"] = float((hit_c[mask].sum() - hit_b[mask].sum()) / n) if n else float("nan")
        kb = np.bincount(codes[mask], weights=hit_b[mask], minlength=n_clusters)
        kc = np.bincount(codes[mask], weights=hit_c[mask], minlength=n_clusters)
        nn = np.bincount(codes[mask], minlength=n_clusters).astype(float)
        keep = nn > 0
        kb, kc, nn = kb[keep], kc[keep], nn[keep]
        if len(nn) < 2:
            lo = hi = float("nan")
        elif np.all(kc == kb):  # identical hits in every recording: the change is exactly zero
            lo = hi = 0.0
        else:
            lo, hi = _bootstrap(
                (kb, kc, nn), lambda kb, kc, nn, axis=-1: (kc.sum(axis=axis) - kb.sum(axis=axis)) / nn.sum(axis=axis),
                seed, level, n_resamples,
            )
        out[f"d_{name}_lo"], out[f"d_{name}_hi"] = lo, hi
    return out


def holm(pvalues: pd.Series | np.ndarray) -> np.ndarray:
    """Holm-adjusted p-values (statsmodels ``multipletests``); NaN stays NaN."""
    p = np.asarray(pvalues, float)
    out = np.full(len(p), np.nan)
    ok = np.isfinite(p)
    if ok.any():
        out[ok] = multipletests(p[ok], method="holm")[1]
    return out
