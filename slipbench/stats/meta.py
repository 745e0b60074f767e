"""One verdict across datasets: the change from one detector to another on each dataset (the
seed-paired contrast of the cells both ran there, :func:`slipbench.stats.contrast.paired_change`)
pooled by a random-effects meta-analysis, as MOABB judges pipelines across datasets.

The pooling takes each dataset's change as its row shows it: its estimate, its standard error
and its degrees of freedom, which give back its interval (``estimate +- t(df) * se``, as
:mod:`slipbench.stats.contrast` makes every interval). The spread between datasets, tau², is
statsmodels' ``combine_effects`` with those standard errors and the Paule-Mandel estimator
(``method_re="iterated"``): with the handful of datasets a lab holds it is less biased than
DerSimonian-Laird's moment estimator, and both agree where the datasets agree. The pooled
change is the random-effects mean (weights ``1 / (se_i² + tau²)``) with a t-interval whose
degrees of freedom are Welch-Satterthwaite's over its parts: each dataset's weighted sampling
variance on that dataset's degrees of freedom, and the weighted tau² on ``k - 1`` (:func:`pool`).
A dataset whose change rests on two seeds thus weighs in with the uncertainty its own interval
shows, not as if its standard error were known; the pooled interval is reproduced from the
shown rows by the same steps (``tests/stats/test_meta.py``). tau² is the variance of the true
change between datasets (accuracy points squared), I² the share of the spread of the datasets'
changes that it explains. With two or three datasets tau² is poorly pinned down: the report says
how many datasets stand behind it.

Rows tested on a dataset other than the one that trained them (transfer, a ``sensor_map``) are
no dataset of their own and never enter. A dataset whose change has no standard error (a
paired cell whose interval is not estimable, named), or a zero one (the same predictions on
both sides), would take every weight: it is listed with the reason and left out of the pooling.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import scipy  # its submodules load on first use: reading stored rows pays none

from slipbench.stats.bootstrap import LEVEL, IntervalSpec
from slipbench.stats.contrast import ONE_SEED, pair_seeds, paired_change

#: statsmodels' name for the Paule-Mandel estimator of tau²
METHOD_RE = "iterated"
METHOD_TEXT = (
    "random effects, Paule-Mandel estimate of tau² (statsmodels combine_effects) from each "
    "dataset's standard error, se = (hi − lo) / (2 t(0.975, df)); the pooled interval a "
    "t-interval, its degrees of freedom Welch-Satterthwaite's over the datasets' and k − 1 for tau²"
)
#: the columns of :attr:`MetaAnalysis.datasets`
DATASET_COLUMNS = [
    "dataset",
    "n_cells",
    "seeds",
    "d",
    "lo",
    "hi",
    "se",
    "df",
    "method",
    "left_out",
    "low_n",
    "reason",
]


@dataclass
class MetaAnalysis:
    """One detector pair across datasets: changes are ``cand`` minus ``base`` accuracy,
    fractions (0.03: 3 points)."""

    base: str
    cand: str
    # one line per dataset holding both detectors: DATASET_COLUMNS; ``reason`` non-empty where
    # the dataset is left out of the pooling
    datasets: pd.DataFrame
    d: float = np.nan
    lo: float = np.nan
    hi: float = np.nan
    se: float = np.nan
    df: float = np.nan
    tau2: float = np.nan
    i2: float = np.nan
    pooled_over: int = 0
    notes: list[str] = field(default_factory=list)


def transferred(rows: pd.DataFrame) -> pd.Series:
    """(n_rows,) bool: rows trained on one dataset and tested on another (a ``sensor_map``)."""
    if "sensor_map" not in rows:
        return pd.Series(False, index=rows.index, dtype=bool)
    return rows["sensor_map"].notna() & rows["sensor_map"].astype(str).ne("")


def pool(
    effects: Sequence[float], ses: Sequence[float], dfs: Sequence[float], level: float = LEVEL
) -> dict:
    """The random-effects pooled change of ``effects`` with standard errors ``ses`` (two or
    more, every one positive) on degrees of freedom ``dfs`` (module docstring): ``d``, ``lo``,
    ``hi``, ``se``, ``df``, ``tau2``, ``i2``."""
    # about a second to import: paid where a pooling needs it, never by a read of stored rows
    from statsmodels.stats.meta_analysis import combine_effects

    d_i, se_i = np.asarray(effects, float), np.asarray(ses, float)
    df_i = np.asarray(dfs, float)
    with np.errstate(divide="ignore"):  # its I² divides by Q; computed below
        res = combine_effects(d_i, se_i**2, method_re=METHOD_RE, alpha=1 - level)
    tau2, k = float(res.tau2), len(d_i)
    w = 1 / (se_i**2 + tau2)
    total = float(w.sum())
    d = float((w * d_i).sum() / total)
    within = w**2 * se_i**2 / total**2  # each dataset's sampling variance in the pooled mean
    between = tau2 * float((w**2).sum()) / total**2
    with np.errstate(divide="ignore", invalid="ignore"):
        spread = float(np.sum(np.where(np.isfinite(df_i), within**2 / df_i, 0.0)))
    spread += between**2 / (k - 1)
    var = float(within.sum()) + between
    df = var**2 / spread if spread > 0 else np.inf
    half = float(scipy.stats.t.ppf(0.5 + level / 2, df) * np.sqrt(var))
    # I² = max(0, (Q - df) / Q); statsmodels divides by Q, which is 0 where the effects agree
    q = float(res.q)
    return {
        "d": d,
        "lo": d - half,
        "hi": d + half,
        "se": float(np.sqrt(var)),
        "df": float(df),
        "tau2": tau2,
        "i2": max(0.0, (q - (k - 1)) / q) if q > 0 else 0.0,
    }


def meta_analysis(
    per_dataset: dict[str, tuple[pd.DataFrame, pd.DataFrame]],
    pair: tuple[str, str],
    folders: Sequence[str | os.PathLike] = (),
    *,
    seed: int = 0,
    level: float = LEVEL,
) -> MetaAnalysis:
    """``per_dataset``: dataset name -> (base's rows, cand's rows) on it, transfer rows already
    left out; ``pair``: the base and candidate detectors' names. Each dataset's seed-paired
    change with its interval at ``level``, then the pooled change."""
    lines, notes = [], []
    for name, (b, c) in per_dataset.items():
        pairing = pair_seeds(b, c, names=pair)
        res = paired_change(pairing, folders=folders, spec=IntervalSpec(seed, level))
        if res.n_cells and res.left_out:  # never dropped unsaid
            notes.append(f"{name}: left out: {'; '.join(res.left_out)}.")
        if res.n_cells and res.missing == ONE_SEED:
            notes.append(f"{name}: {ONE_SEED}, nor in the pooled one.")
        reason = ""
        if res.n_cells == 0:
            reason = res.missing + (f" ({'; '.join(res.left_out)})" if res.left_out else "")
        elif res.missing not in ("", ONE_SEED):
            # what the change lacks, naming the cells: a cell's interval not estimable
            reason = res.missing
        elif not np.isfinite(res.se):
            reason = "no standard error in its rows"
        elif res.se <= 0:
            reason = "no spread (zero standard error: the two sides scored alike)"
        lines.append(
            {
                "dataset": name,
                "n_cells": res.n_cells,
                "seeds": ",".join(map(str, res.seeds)),
                "d": res.estimate,
                "lo": res.lo,
                "hi": res.hi,
                "se": res.se,
                "df": res.df,
                "method": res.method,
                "left_out": "; ".join(res.left_out),
                "low_n": pairing.low_n,
                "reason": reason,
            }
        )
    frame = pd.DataFrame(lines, columns=DATASET_COLUMNS)
    out = MetaAnalysis(*pair, frame, notes=notes)
    used = frame[frame["reason"] == ""]
    out.pooled_over = len(used)
    if len(used) < 2:
        out.notes.append(
            f"{len(used)} dataset with a change to pool: no pooled change (it needs two or more)."
            if len(used) == 1
            else "No dataset with a change to pool."
        )
        return out
    pooled = pool(used["d"], used["se"], used["df"], level)
    out.d, out.lo, out.hi, out.se, out.df = (pooled[k] for k in ("d", "lo", "hi", "se", "df"))
    out.tau2, out.i2 = pooled["tau2"], pooled["i2"]
    if len(used) < 4:
        out.notes.append(
            f"tau² rests on {len(used)} datasets: the spread between datasets is poorly pinned down."
        )
    return out
