"""The report's "Across datasets" section: for each pair of detectors, the change on each
dataset, the random-effects pooled change and the spread between datasets
(:mod:`slipbench.stats.meta`), as a table and a forest plot."""

from __future__ import annotations

import os
from collections.abc import Sequence
from functools import partial
from itertools import combinations
from pathlib import PurePath

import numpy as np
import pandas as pd

from slipbench.report.blocks import LOW_MARK, Heading, Table, Text
from slipbench.report.order import rank
from slipbench.report.outline import splits_of
from slipbench.report.versus import DIFFER_WORDS
from slipbench.stats.contrast import margin_of, state_of
from slipbench.stats.meta import METHOD_TEXT, MetaAnalysis, meta_analysis, transferred
from slipbench.store.columns import ACCURACY
from slipbench.vocabulary import DETECTOR_ORDER, LOW_N

TITLE = "Across datasets"


def dataset_names(rows: pd.DataFrame) -> pd.Series:
    """Each row's dataset, named by its file (``dataset_path``) where the rows give it, else by
    its fingerprint's start; two datasets of one file name get their fingerprint's start too."""
    prints = rows["dataset_fingerprint"].astype(str)
    paths = rows["dataset_path"] if "dataset_path" in rows else pd.Series("", index=rows.index)
    names = [
        PurePath(str(p)).name if isinstance(p, str) and p else f[:12] for p, f in zip(paths, prints)
    ]
    out = pd.Series(names, index=rows.index)
    clash = out.groupby(out).transform(lambda s: prints[s.index].nunique() > 1)
    return out.where(~clash, out + " (" + prints.str[:8] + ")")


def _pairs(detectors: list[str], reference: Sequence[str]) -> list[tuple[str, str]]:
    """Every pair once, the reference (else the first in the tables' order) as the base."""
    out = []
    for a, b in combinations(detectors, 2):
        out.append((b, a) if b in reference and a not in reference else (a, b))
    return out


def analyses(
    rows: pd.DataFrame,
    reference: Sequence[str] = (),
    folders: Sequence[str | os.PathLike] = (),
    seed: int = 0,
) -> list[MetaAnalysis]:
    """One :class:`~slipbench.stats.meta.MetaAnalysis` per pair of detectors (entrants) that
    share a cell on some dataset, on the first split (the grouped one where present); none with
    fewer than two datasets. Transfer rows never enter."""
    if "dataset_fingerprint" not in rows or "detector" not in rows:
        return []
    rows = rows[~transferred(rows) & rows["dataset_fingerprint"].notna()]
    if rows.empty:
        return []
    rows = splits_of(rows)[0][1]
    rows = rows.assign(_dataset=dataset_names(rows))
    if rows["_dataset"].nunique() < 2:
        return []
    detectors = rank(rows["detector"].unique(), DETECTOR_ORDER)
    out = []
    for base, cand in _pairs(detectors, reference):
        per = {
            name: (part[part["detector"] == base], part[part["detector"] == cand])
            for name, part in rows.groupby("_dataset", sort=True)
            if {base, cand} <= set(part["detector"])
        }
        if per:
            out.append(meta_analysis(per, (base, cand), folders, seed=seed))
    return out


def _change(d: float, lo: float, hi: float, df: float = np.nan) -> str:
    """``+4.1 [-0.3, +8.6] (df 12)``: a change in points with the interval and degrees of
    freedom the pooling reads (:func:`slipbench.stats.meta.pool`)."""
    if not np.isfinite(d):
        return "—"
    shown = f"{100 * d:+.1f}"
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return shown
    shown += f" [{100 * lo:+.1f}, {100 * hi:+.1f}]"
    return shown + (f" (df {df:.3g})" if np.isfinite(df) else " (df ∞)" if df == np.inf else "")


def summary_table(metas: list[MetaAnalysis]) -> Table:
    """A line per pair: its change on each dataset and pooled, tau², I², datasets pooled."""
    datasets = sorted({n for m in metas for n in m.datasets["dataset"]})
    cells, notes = [], []
    for m in metas:
        per = m.datasets.set_index("dataset")
        line = [
            _change(*per.loc[n, ["d", "lo", "hi", "df"]]) + LOW_MARK * bool(per.loc[n, "low_n"])
            if n in per.index
            else "not run"
            for n in datasets
        ]
        pooled = np.isfinite(m.d)
        line += [
            _change(m.d, m.lo, m.hi, m.df) if pooled else "—",
            DIFFER_WORDS[state_of(m.lo, m.hi, margin_of(ACCURACY.name))] if pooled else "—",
            f"{1e4 * m.tau2:.2f}" if pooled else "—",
            f"{100 * m.i2:.0f} %" if pooled else "—",
            str(m.pooled_over),
        ]
        cells.append(line)
        who = f"{m.cand} − {m.base}: "
        notes += [
            f"{who}{r['dataset']} left out: {r['reason']}."
            for r in per.reset_index().to_dict("records")
            if r["reason"]
        ]
        notes += [who + n for n in m.notes]
        low = per[per["low_n"] > 0]
        notes += [
            f"{who}{name}: {LOW_MARK} {int(n)} of its paired cells rest on few test trials (fewer "
            f"than {LOW_N} of a class): its change is not to be trusted, nor the pooled one."
            for name, n in low["low_n"].items()
        ]
    return Table(
        "Change in accuracy (points) per detector pair, on each dataset and pooled across them.",
        ["Pair"],
        "Change in accuracy (points) [95 % interval]",
        [*datasets, "Pooled", "Differ", "tau² (points²)", "I²", "Datasets pooled"],
        [(f"{m.cand} − {m.base}",) for m in metas],
        cells,
        "tab:meta",
        notes=[
            "Each dataset: the mean over the cells and seeds both detectors finished there of "
            "the difference in accuracy, paired seed by seed, with its 95 % interval "
            "(estimate ± t(0.975, df) × se) and degrees of freedom. Pooled: "
            f"{METHOD_TEXT}; tau²: the variance of the true change between datasets; I²: the "
            "share of the spread between datasets that is not sampling noise. Differ: yes where "
            f"the pooled interval lies beyond ±{100 * margin_of(ACCURACY.name):g} point, no where "
            "it lies inside it, else undecided, as every contrast reads. Rows trained on "
            "one dataset and tested on another do not enter.",
            *notes,
        ],
    )


def meta_blocks(
    rows: pd.DataFrame,
    reference: Sequence[str] = (),
    predictions: Sequence[str | os.PathLike] = (),
    with_figures: bool = False,
    seed: int = 0,
) -> list:
    """The section's blocks, or none where the rows hold fewer than two datasets."""
    metas = analyses(rows, reference, predictions, seed)
    if not metas:
        return []
    blocks: list = [
        Heading(TITLE, 2),
        Text(
            f"Each pair of detectors on each of the {len(metas[0].datasets)} or more datasets "
            "these results hold, and one verdict across them: a pooled change whose interval "
            f"lies beyond ±{100 * margin_of(ACCURACY.name):g} point (the accuracy's margin) says which detector "
            "wins across the datasets; tau² and I² say how much "
            "that change differs from dataset to dataset."
        ),
        summary_table(metas),
    ]
    if with_figures:
        from slipbench.report.plots import FigureSpec, forest

        blocks.append(
            FigureSpec(
                "meta",
                "Across datasets: each pair's change in accuracy (points) on each dataset (dot, "
                "its 95 % interval a bar) and pooled (diamond, its interval a bar).",
                TITLE,
                partial(forest, metas),
            )
        )
    return blocks
