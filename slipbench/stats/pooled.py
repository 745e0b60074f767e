"""The mean change of a rate over many compared cells, with ONE joint cluster bootstrap.

A change spread thinly over a protocol (every window of a tenth of the trials flipped in all
window-size cells: -4.6 points on average) hides inside each cell's simultaneous interval, but
not inside the interval of the mean over the cells. The cells of a protocol test the same
trials (fingers recorded at once, windows cut from the same recordings), so their changes move
together: the mean is bootstrapped once, every resample drawing each trial for all cells and
both sides at once (clusters shared by test sets are one cluster, as in
:func:`slipbench.stats.metrics.mean_over_test_sets`).

Seeds (``--repeats``): a cell's change is the mean over the candidate's seeds minus the mean
over the base's; the trial bootstrap covers the test noise of all of them. Retraining noise is
added as a second variance component, the between-seed variance of each cell's figure over its
seeds divided by their number (the textbook two-level variance of a mean of seed means), for
each side holding at least two seeds. Seeds test on differently drawn windows, so that spread
holds some test noise again: the sum errs wide. Degrees of freedom combine by
Welch-Satterthwaite (the seed part has seeds - 1 per side and cell).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import t as student_t

from slipbench.stats.bootstrap import N_RESAMPLES, interval, make_design
from slipbench.stats.metrics import Predictions, classes_low_n, cluster_counts

RATE_MASKS = ("accuracy", "tp_rate", "tn_rate")


@dataclass(frozen=True)
class CellSides:
    """One compared cell: one Predictions per seed on each side."""

    base: Sequence[Predictions]
    cand: Sequence[Predictions]


def _mask(p: Predictions, figure: str) -> np.ndarray:
    y = np.asarray(p.y_true, bool)
    return {"accuracy": np.ones(len(y), bool), "tp_rate": y, "tn_rate": ~y}[figure]


def pooled_change(
    cells: Sequence[CellSides],
    seed: int,
    level: float,
    figure: str = "accuracy",
    n_resamples: int = N_RESAMPLES,
) -> dict:
    """The mean over ``cells`` of (candidate - base) of ``figure`` (a rate, as a fraction),
    with an interval at ``level`` from one joint stratified cluster bootstrap over the trials
    (plus the seeds' variance where a side holds several).

    Returns
    -------
    dict
        ``d``, ``lo``, ``hi``, ``se``, ``df``; ``se_seeds`` (the retraining part, 0 with one
        seed per side); ``n_cells``; ``n_test_clusters_slip``/``_nonslip`` over the union of the
        test sets and ``low_n``; ``estimable``.
    """
    if figure not in RATE_MASKS:
        raise ValueError(f"pooled changes are of rates ({', '.join(RATE_MASKS)}), not {figure}")
    if not cells:
        raise ValueError("pooled_change needs at least one cell")
    parts = [p for c in cells for p in (*c.base, *c.cand)]
    design, codes = make_design([p.y_true for p in parts], [p.groups for p in parts])
    hits, size = [], []
    for p, c in zip(parts, codes):
        m = _mask(p, figure)
        correct = (np.asarray(p.y_true, bool) == np.asarray(p.y_pred, bool)).astype(float)
        hits.append(np.bincount(c[m], weights=correct[m], minlength=design.n_clusters))
        size.append(np.bincount(c[m], minlength=design.n_clusters).astype(float))
    # the weight of each test set in the mean change: +-1 / (cells x seeds of its side)
    weights: list[float] = []
    for cell in cells:
        for side, sign in ((cell.base, -1.0), (cell.cand, 1.0)):
            weights += [sign / (len(cells) * len(side))] * len(side)
    H, S, a = np.array(hits), np.array(size), np.array(weights)

    def statistic(w: np.ndarray) -> np.ndarray:
        return ((w @ H.T) / (w @ S.T)) @ a

    def influence(w: np.ndarray) -> np.ndarray:
        denom = w @ S.T  # (n, parts)
        r = (w @ H.T) / denom
        # d ratio_k / d w_j = (H_kj - r_k S_kj) / denom_k
        return ((a / denom)[:, :, None] * (H[None] - r[:, :, None] * S[None])).sum(axis=1)

    used = S.sum(axis=0) > 0
    iv = interval(
        statistic,
        influence,
        design,
        used,
        S.sum(axis=0),
        seed,
        level,
        n_resamples,
        bounds=(-1.0, 1.0),
    )
    # retraining noise: between-seed variance of each cell's figure on a side of >= 2 seeds
    with np.errstate(invalid="ignore", divide="ignore"):
        per_set = H.sum(axis=1) / S.sum(axis=1)
    seed_terms, k = [], 0
    for cell in cells:
        for side in (cell.base, cell.cand):
            values = per_set[k : k + len(side)]
            k += len(side)
            if len(side) > 1 and np.isfinite(values).all():
                seed_terms.append((values.var(ddof=1) / len(side) / len(cells) ** 2, len(side) - 1))
    v_seed = float(sum(v for v, _ in seed_terms))
    out = {
        "n_cells": len(cells),
        "estimable": bool(iv.estimable),
        "d": float(iv.estimate),
        "se_seeds": float(np.sqrt(v_seed)),
    }
    y = np.concatenate([np.asarray(p.y_true, bool) for p in parts])
    g = np.concatenate([np.asarray(p.groups) for p in parts])
    n_slip, n_nonslip = cluster_counts(y, g)
    out |= {
        "n_test_clusters_slip": n_slip,
        "n_test_clusters_nonslip": n_nonslip,
        "low_n": classes_low_n(n_slip, n_nonslip),
    }
    if not iv.estimable or not np.isfinite(iv.se):
        return out | {"lo": iv.lo, "hi": iv.hi, "se": np.nan, "df": np.nan}
    v_trial = iv.se**2
    se = float(np.sqrt(v_trial + v_seed))
    if v_seed > 0:
        df = (v_trial + v_seed) ** 2 / (
            v_trial**2 / iv.df + sum(v**2 / dfv for v, dfv in seed_terms)
        )
    else:
        df = iv.df
    if se == 0:
        return out | {"lo": iv.estimate, "hi": iv.estimate, "se": 0.0, "df": float(df)}
    q = student_t.ppf(1 - (1 - level) / 2, df)
    return out | {
        "lo": float(max(iv.estimate - q * se, -1.0)),
        "hi": float(min(iv.estimate + q * se, 1.0)),
        "se": se,
        "df": float(df),
    }
