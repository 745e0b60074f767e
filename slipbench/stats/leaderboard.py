"""Which detector wins: ranks over cells, a Friedman test, Wilcoxon-Holm post hoc, mean figures.

The method is the one the time-series classification literature uses to compare classifiers
over many datasets (Demšar 2006; Benavoli et al. 2016; aeon's critical-difference diagrams),
with a protocol *cell* in the role of a dataset:

1. each detector's figure per cell is the mean over its seeds (``--repeats``);
2. only cells where every detector finished are ranked (a complete block design); the others
   are counted and reported as excluded;
3. per cell the detectors are ranked, 1 = best, ties sharing the mean rank
   (``scipy.stats.rankdata``); a detector's score in a scope is its mean rank over the scope's
   cells: per protocol, and over every cell at once (so a protocol weighs by its cell count);
4. the Friedman test (``scipy.stats.friedmanchisquare``, three detectors or more) asks whether
   any detector differs; each pair is then compared by a Wilcoxon signed-rank test on its
   per-cell figures, p-values Holm-corrected within the scope (``statsmodels``), and detectors
   no pair of which differs at ``ALPHA`` form a group, drawn as one bar in the diagram.

A block is counted once: cells that test the same model on the same test windows (the
sampling rate's full-rate cells are the window-size window-200 cells; with ``decimation=both``
three of them) are duplicates, found by the rows' model keys and test parts
(:func:`block_signature`), and merged into one block before anything is ranked, tested or
averaged. Blocks still share recordings (window 50 of one unit appears in several protocols,
each with another model or test set), so they are not independent: the tests' p-values are
optimistic, and the report says so.

Each pair of detectors also gets its mean difference over the ranked blocks with a percentile
bootstrap interval over blocks (blocks resampled, each block's figure fixed, every pair on the
same draws) and a bootstrap p-value, Holm-adjusted over the pairs (:func:`pairwise`).

Mean accuracy, balanced accuracy and AUROC are over the same ranked cells, so they compare.
Their 95 % interval is a percentile bootstrap over cells (cells resampled, each cell's figure
fixed): it shows how the mean depends on which conditions make up the benchmark, not the test
noise within a cell, which the per-cell intervals show.

This module computes; the tables that show the leaderboard are the report wing's.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.stats import bootstrap, friedmanchisquare, rankdata, wilcoxon
from statsmodels.stats.multitest import multipletests

from slipbench.seeding import rng_for

ALPHA = 0.05
LEVEL = 0.95
N_RESAMPLES = 2000
ALL = "all"
#: columns that, with the cell's key, name one cell across detectors
CELL_IDENTITY = ("protocol", "split", "labels", "dataset_fingerprint", "cell")
#: columns that, with the model key, name the windows a cell is scored on
TEST_IDENTITY = ("test_sensors", "test_where", "test_stream")
MEAN_METRICS = ("accuracy", "balanced_accuracy", "auroc")


@dataclass
class Scope:
    """The ranking of one protocol's cells (or of every cell, ``name == ALL``).

    Attributes
    ----------
    name : the protocol, or ``ALL``.
    n_cells : blocks ranked (every detector finished them), duplicates merged.
    n_excluded : cells some detector did not finish (failed, skipped or absent).
    ranks : entrant -> mean rank (1 = best), best first.
    wins : entrant -> cells where it ranked first (a tie counts for each tied entrant).
    friedman : (chi-square, p), or None with fewer than three entrants or two cells.
    pairs : one row per pair: ``a``, ``b`` (a ranked above b), ``p`` (Wilcoxon), ``p_holm``,
        ``differ`` (p_holm < ALPHA).
    groups : runs of entrants, in rank order, no two of which differ: the diagram's bars.
    """

    name: str
    n_cells: int
    n_excluded: int
    ranks: pd.Series
    wins: pd.Series
    friedman: tuple[float, float] | None
    pairs: pd.DataFrame
    groups: list[list[str]]
    n_duplicates: int = 0  # finished cells merged into a block another cell already stands for


@dataclass
class Leaderboard:
    """Ranks, tests and mean figures of the detectors in a set of result rows.

    Attributes
    ----------
    metric : the figure ranked ("accuracy", ...).
    scopes : ``ALL`` first, then each protocol in the order given.
    means : entrant x (metric, "lo", "hi") over the ranked cells of ``ALL``: columns
        ``<m>``, ``<m>_lo``, ``<m>_hi`` for each of MEAN_METRICS, and ``<m>_cells`` (cells
        with a value: balanced accuracy and AUROC do not exist on a one-class test set).
    entrants : entrant -> the detector and parameters it stands for.
    pairs : :func:`pairwise` over the ranked blocks of ``ALL``.
    """

    metric: str
    scopes: list[Scope]
    means: pd.DataFrame
    entrants: dict[str, str] = field(default_factory=dict)
    pairs: pd.DataFrame = field(default_factory=lambda: pairwise(pd.DataFrame(), []))

    @property
    def order(self) -> list[str]:
        """Entrants by overall mean rank, best first."""
        return list(self.scopes[0].ranks.index) if self.scopes else []

    def scope(self, name: str) -> Scope | None:
        return next((s for s in self.scopes if s.name == name), None)


def entrants(rows: pd.DataFrame) -> pd.Series:
    """Who competes: the detector's id, or, where one detector ran with several parameter
    sets, its id with the parameters that differ (``holweg (band=[39, 100])``)."""
    if "detector_params" not in rows:
        return rows["detector"].astype(str)
    out = rows["detector"].astype(str).copy()
    for det, part in rows.groupby("detector", sort=False):
        texts = part["detector_params"].fillna("{}").unique()
        if len(texts) < 2:
            continue
        params = {t: json.loads(t) for t in texts}
        varying = sorted(
            {
                k
                for p in params.values()
                for k in p
                if len({json.dumps(q.get(k)) for q in params.values()}) > 1
            }
        )
        names = {
            t: f"{det} ({', '.join(f'{k}={json.dumps(p.get(k))}' for k in varying)})"
            for t, p in params.items()
        }
        out[part.index] = part["detector_params"].fillna("{}").map(names)
    return out


def cell_table(rows: pd.DataFrame, metric: str) -> pd.DataFrame:
    """(n_cells, n_entrants) figure per cell: the mean over seeds of the ok rows; NaN where an
    entrant has no finished row of the cell. Index: the cell identity columns the rows hold."""
    ident = [c for c in CELL_IDENTITY if c in rows]
    ok = rows[rows["status"] == "ok"] if "status" in rows else rows
    ok = ok.assign(
        _entrant=entrants(rows).loc[ok.index], _value=pd.to_numeric(ok.get(metric), errors="coerce")
    )
    every = rows.assign(_entrant=entrants(rows))[[*ident, "_entrant"]].drop_duplicates()
    table = (
        ok.groupby([*ident, "_entrant"], sort=False, dropna=False)["_value"]
        .mean()
        .unstack("_entrant")
    )
    cells = every[ident].drop_duplicates().set_index(ident).index
    return table.reindex(index=cells, columns=every["_entrant"].unique())


def block_signature(rows: pd.DataFrame) -> pd.Series:
    """Per cell (the index of :func:`cell_table`): what it measures, as one hashable value.

    Two cells measure the same thing when every row of one has a row of the other with the
    same model key (data, split, seed, detector, training windows, window, rate) and the same
    test part (sensors, filters, streaming or not): the same model on the same test windows.
    A cell some row of which lacks its model key (rows of an old version) is its own block.
    """
    ident = [c for c in CELL_IDENTITY if c in rows]
    if rows.empty:
        return pd.Series(dtype=object)
    cols = ["model_key", *TEST_IDENTITY]
    parts = pd.DataFrame(
        {c: rows[c].astype(str) if c in rows else pd.Series("", index=rows.index) for c in cols}
    )
    if "test_stream" not in rows and "stream_s" in rows:  # rows written before test_stream
        parts["test_stream"] = rows["stream_s"].notna().map({True: "stream", False: ""})
    known = rows["model_key"].notna() if "model_key" in rows else pd.Series(False, rows.index)
    parts["_sig"] = parts[cols].agg("|".join, axis=1)
    parts["_known"] = known
    out = {}
    for cell, group in parts.join(rows[ident]).groupby(ident, sort=False, dropna=False):
        cell = cell if isinstance(cell, tuple) else (cell,)
        out[cell] = tuple(sorted(set(group["_sig"]))) if group["_known"].all() else ("cell", *cell)
    index = pd.MultiIndex.from_tuples(list(out), names=ident)
    return pd.Series(list(out.values()), index=index, dtype=object)


def merge_blocks(table: pd.DataFrame, signature: pd.Series) -> tuple[pd.DataFrame, int]:
    """``table`` (cells x entrants) with duplicate cells merged: one line per block, at its first
    cell, each entrant's figure the mean over the block's cells that hold one (the same model
    on the same windows: equal where both finished). Returns the blocks and how many finished
    cells were merged into a block another cell already stood for."""
    if table.empty:
        return table, 0
    sig = signature.reindex(table.index)
    # a cell the signature does not know (no rows of it): its own block
    sig = pd.Series(
        [s if isinstance(s, tuple) else ("cell", *i) for i, s in zip(table.index, sig)],
        index=table.index,
    )
    codes = pd.Series(pd.factorize(sig)[0], index=table.index)
    first = ~codes.duplicated()
    merged = table.groupby(codes.to_numpy(), sort=False).mean()
    merged.index = table.index[first.to_numpy()]
    complete = table.notna().all(axis=1)
    n_dup = int(complete.sum()) - int(
        merged.notna().all(axis=1).reindex(table.index[first.to_numpy()]).sum()
    )
    return merged, max(n_dup, 0)


def pairwise(blocks: pd.DataFrame, order: list[str], seed: int = 0) -> pd.DataFrame:
    """Every pair (a ranked above b): the mean of a - b over the complete ``blocks``, its
    percentile bootstrap interval over blocks (each block's figure fixed; every pair on the same
    draws), the bootstrap p-value of no difference, and that p Holm-adjusted over the pairs.
    Columns: a, b, diff, lo, hi, p, p_holm, differ (p_holm < ALPHA)."""
    columns = ["a", "b", "diff", "lo", "hi", "p", "p_holm", "differ"]
    complete = blocks[order].dropna() if len(order) else blocks.iloc[:0]
    n = len(complete)
    if n == 0 or len(order) < 2:
        return pd.DataFrame(columns=columns)
    draws = rng_for(seed, "leaderboard-pairs").integers(0, n, (N_RESAMPLES, n))
    out = []
    for i, a in enumerate(order):
        for b in order[i + 1 :]:
            d = complete[a].to_numpy(dtype=float) - complete[b].to_numpy(dtype=float)
            boot = d[draws].mean(axis=1)
            q = (1 - LEVEL) / 2
            lo, hi = np.quantile(boot, [q, 1 - q]) if n > 1 else (np.nan, np.nan)
            if np.all(d == 0):
                p = 1.0
            elif n < 2:
                p = np.nan
            else:  # two-sided: how often a resample lands on zero or beyond it
                below = (np.sum(boot <= 0) + 1) / (N_RESAMPLES + 1)
                above = (np.sum(boot >= 0) + 1) / (N_RESAMPLES + 1)
                p = min(1.0, 2 * min(below, above))
            out.append({"a": a, "b": b, "diff": float(d.mean()), "lo": lo, "hi": hi, "p": p})
    pairs = pd.DataFrame(out, columns=columns[:6])
    finite = pairs["p"].notna()
    pairs["p_holm"] = np.nan
    if finite.any():
        pairs.loc[finite, "p_holm"] = multipletests(pairs.loc[finite, "p"], method="holm")[1]
    pairs["differ"] = pairs["p_holm"] < ALPHA
    return pairs


def _holm_pairs(scores: pd.DataFrame, order: list[str]) -> pd.DataFrame:
    """Wilcoxon signed-rank test of each pair over cells, Holm-corrected across the pairs."""
    out = []
    for i, a in enumerate(order):
        for b in order[i + 1 :]:
            d = scores[a].to_numpy() - scores[b].to_numpy()
            # zsplit keeps tied cells in the count (they favour neither); all ties: no evidence
            p = (
                1.0
                if len(d) == 0 or np.all(d == 0)
                else float(wilcoxon(d, zero_method="zsplit").pvalue)
            )
            out.append({"a": a, "b": b, "p": p})
    pairs = pd.DataFrame(out, columns=["a", "b", "p"])
    if len(pairs):
        pairs["p_holm"] = multipletests(pairs["p"], method="holm")[1]
    else:
        pairs["p_holm"] = []
    pairs["differ"] = pairs["p_holm"] < ALPHA
    return pairs


def _groups(order: list[str], pairs: pd.DataFrame) -> list[list[str]]:
    """Maximal runs of rank-ordered entrants no two of which differ (the diagram's bars)."""
    differ = {(a, b) for a, b, d in pairs[["a", "b", "differ"]].itertuples(index=False) if d}
    runs: list[tuple[int, int]] = []  # (first, last) positions in ``order``
    for i in range(len(order)):
        j = i
        while j + 1 < len(order) and not any(
            (order[k], order[j + 1]) in differ for k in range(i, j + 1)
        ):
            j += 1
        if j > i and not any(s <= i and j <= e for s, e in runs):
            runs.append((i, j))
    return [order[s : e + 1] for s, e in runs]


def rank_scope(scores: pd.DataFrame, name: str) -> Scope:
    """Rank the entrants (columns) over the complete cells (rows) of ``scores``."""
    complete = scores.dropna()
    n_excluded = len(scores) - len(complete)
    if complete.empty or scores.shape[1] == 0:
        empty = pd.Series(dtype=float)
        return Scope(name, 0, n_excluded, empty, empty, None, _holm_pairs(complete, []), [])
    ranks = pd.DataFrame(
        rankdata(-complete.to_numpy(), axis=1), index=complete.index, columns=complete.columns
    )
    mean = ranks.mean().sort_values(kind="stable")
    order = list(mean.index)
    wins = (ranks == ranks.min(axis=1).to_numpy()[:, None]).sum()[order]
    friedman = None
    if len(order) >= 3 and len(complete) >= 2:
        stat, p = friedmanchisquare(*(complete[c].to_numpy() for c in order))
        friedman = (float(stat), float(p)) if np.isfinite(stat) else (0.0, 1.0)  # every cell tied
    pairs = _holm_pairs(complete, order)
    return Scope(
        name, len(complete), n_excluded, mean, wins, friedman, pairs, _groups(order, pairs)
    )


def _mean_interval(values: np.ndarray, seed: int = 0) -> tuple[float, float, float]:
    """The mean of the finite values and its percentile bootstrap interval over them."""
    values = values[np.isfinite(values)]
    if len(values) < 2:
        return (float(values[0]) if len(values) else np.nan), np.nan, np.nan
    if np.all(
        values == values[0]
    ):  # nothing to resample; scipy would warn of a degenerate distribution
        return float(values[0]), float(values[0]), float(values[0])
    res = bootstrap(
        (values,),
        np.mean,
        n_resamples=N_RESAMPLES,
        confidence_level=LEVEL,
        method="percentile",
        rng=rng_for(seed, "leaderboard"),
    )
    return (
        float(values.mean()),
        float(res.confidence_interval.low),
        float(res.confidence_interval.high),
    )


def leaderboard(
    rows: pd.DataFrame, metric: str = "accuracy", protocols: list[str] | None = None
) -> Leaderboard:
    """Rank the detectors in ``rows`` (result rows of one or more detectors) by ``metric``.

    Parameters
    ----------
    rows : result rows as ``evaluate`` writes them (any statuses; only "ok" rows count).
    metric : the figure ranked; higher is better.
    protocols : the per-protocol scopes, in order (default: as the rows first name them).
    """
    who = entrants(rows)
    names = {e: _params_text(rows.loc[who == e]) for e in who.unique()}
    protocols = list(dict.fromkeys(rows["protocol"])) if protocols is None else protocols
    table = cell_table(rows, metric)
    signature = block_signature(rows)

    def scope(part: pd.DataFrame, name: str) -> tuple[Scope, pd.DataFrame]:
        blocks, n_dup = merge_blocks(part, signature)
        ranked = rank_scope(blocks, name)
        ranked.n_duplicates = n_dup
        return ranked, blocks

    overall, blocks = scope(table, ALL)
    scopes = [overall]
    for protocol in protocols:
        part = table[table.index.get_level_values("protocol") == protocol]
        if len(part):
            scopes.append(scope(part, protocol)[0])
    ranked = blocks.dropna().index
    means = pd.DataFrame(index=pd.Index(overall.ranks.index, name=None))
    for m in MEAN_METRICS:
        values = (
            merge_blocks(cell_table(rows, m), signature)[0].reindex(ranked)
            if m != metric
            else blocks.reindex(ranked)
        )
        for e in means.index:
            x = values[e].to_numpy(dtype=float)
            means.loc[e, [m, f"{m}_lo", f"{m}_hi"]] = _mean_interval(x)
            means.loc[e, f"{m}_cells"] = int(np.isfinite(x).sum())
    return Leaderboard(metric, scopes, means, names, pairwise(blocks, list(overall.ranks.index)))


def _params_text(rows: pd.DataFrame) -> str:
    det = str(rows["detector"].iloc[0])
    params = rows["detector_params"].dropna().unique() if "detector_params" in rows else []
    return f"{det} {params[0]}" if len(params) else det
