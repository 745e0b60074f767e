"""One verdict across datasets: the change from one detector to another on each dataset
(:func:`slipbench.stats.pairs.paired_change`, over the cells both ran there) pooled by a
random-effects meta-analysis, as MOABB judges pipelines across datasets.

The pooling is statsmodels' ``combine_effects`` with the Paule-Mandel estimator of the spread
between datasets (``method_re="iterated"``): with the handful of datasets a lab holds it is less
biased than DerSimonian-Laird's moment estimator, and both agree where the datasets agree. Each
dataset's variance is its change's squared standard error; the pooled interval is normal
(statsmodels' default). tau² is the variance of the true change between datasets (accuracy
points squared), I² the share of the spread of the datasets' changes that it explains. With two
or three datasets tau² is poorly pinned down: the report says how many datasets stand behind it.

Rows tested on a dataset other than the one that trained them (transfer, a ``sensor_map``) are
no dataset of their own and never enter. A dataset whose change has no standard error, or a
zero one (the same predictions on both sides), would take every weight: it is listed with the
reason and left out of the pooling.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from slipbench.stats.metrics import LEVEL
from slipbench.stats.pairs import paired_change

#: statsmodels' name for the Paule-Mandel estimator of tau²
METHOD_RE = "iterated"
METHOD_TEXT = "random effects, Paule-Mandel estimate of tau² (statsmodels combine_effects)"
#: the columns of :attr:`MetaAnalysis.datasets`
DATASET_COLUMNS = ["dataset", "n_cells", "d", "lo", "hi", "se", "method", "reason"]


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
    tau2: float = np.nan
    i2: float = np.nan
    pooled_over: int = 0
    notes: list[str] = field(default_factory=list)


def transferred(rows: pd.DataFrame) -> pd.Series:
    """(n_rows,) bool: rows trained on one dataset and tested on another (a ``sensor_map``)."""
    if "sensor_map" not in rows:
        return pd.Series(False, index=rows.index, dtype=bool)
    return rows["sensor_map"].notna() & rows["sensor_map"].astype(str).ne("")


def pool(effects: Sequence[float], ses: Sequence[float], level: float = LEVEL) -> dict:
    """The random-effects pooled change of ``effects`` with standard errors ``ses`` (two or
    more, every one positive): ``d``, ``lo``, ``hi``, ``tau2``, ``i2``."""
    from statsmodels.stats.meta_analysis import combine_effects  # see slipbench.stats

    with np.errstate(divide="ignore"):  # its I² divides by Q; computed below
        res = combine_effects(
            np.asarray(effects, float),
            np.asarray(ses, float) ** 2,
            method_re=METHOD_RE,
            alpha=1 - level,
        )
    lo, hi = res.conf_int(alpha=1 - level)[1]
    # I² = max(0, (Q - df) / Q); statsmodels divides by Q, which is 0 where the effects agree
    q, df = float(res.q), len(effects) - 1
    return {
        "d": float(res.mean_effect_re),
        "lo": float(lo),
        "hi": float(hi),
        "tau2": float(res.tau2),
        "i2": max(0.0, (q - df) / q) if q > 0 else 0.0,
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
    left out; ``pair``: the base and candidate detectors' names. Each dataset's change with its interval at ``level``, then the pooled change."""
    lines, notes = [], []
    for name, (b, c) in per_dataset.items():
        res = paired_change(b, c, folders, seed, level)
        if res["n_cells"] and res["n_skipped"]:  # never dropped unsaid
            notes.append(f"{name}: {res['n_skipped']} shared cells left out, a seed stored twice.")
        reason = ""
        if res["n_cells"] == 0:
            reason = (
                f"each of its {res['n_skipped']} shared cells holds a seed stored twice"
                if res["n_skipped"]
                else "no cell that both detectors finished"
            )
        elif not np.isfinite(res["se"]):
            reason = "no standard error in its rows"
        elif res["se"] <= 0:
            reason = "no spread (zero standard error: the two sides scored alike)"
        lines.append(
            {"dataset": name, **{k: res[k] for k in DATASET_COLUMNS[1:-1]}, "reason": reason}
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
    res = pool(used["d"], used["se"], level)
    out.d, out.lo, out.hi, out.tau2, out.i2 = (res[k] for k in ("d", "lo", "hi", "tau2", "i2"))
    if len(used) < 4:
        out.notes.append(
            f"tau² rests on {len(used)} datasets: the spread between datasets is poorly pinned down."
        )
    return out
