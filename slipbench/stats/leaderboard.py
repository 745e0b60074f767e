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

Cells share recordings (window 50 of one unit appears in four protocols), so they are not
independent blocks: the tests' p-values are optimistic, and the report says so.

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
MEAN_METRICS = ("accuracy", "balanced_accuracy", "auroc")


@dataclass
class Scope:
    """The ranking of one protocol's cells (or of every cell, ``name == ALL``).

    Attributes
    ----------
    name : the protocol, or ``ALL``.
    n_cells : cells ranked (every detector finished them).
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
    """

    metric: str
    scopes: list[Scope]
    means: pd.DataFrame
    entrants: dict[str, str] = field(default_factory=dict)

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
    scopes = [rank_scope(table, ALL)]
    for protocol in protocols:
        part = table[table.index.get_level_values("protocol") == protocol]
        if len(part):
            scopes.append(rank_scope(part, protocol))
    ranked = table.dropna().index
    means = pd.DataFrame(index=pd.Index(scopes[0].ranks.index, name=None))
    for m in MEAN_METRICS:
        values = cell_table(rows, m).reindex(ranked) if m != metric else table.reindex(ranked)
        for e in means.index:
            x = values[e].to_numpy(dtype=float)
            means.loc[e, [m, f"{m}_lo", f"{m}_hi"]] = _mean_interval(x)
            means.loc[e, f"{m}_cells"] = int(np.isfinite(x).sum())
    return Leaderboard(metric, scopes, means, names)


def _params_text(rows: pd.DataFrame) -> str:
    det = str(rows["detector"].iloc[0])
    params = rows["detector_params"].dropna().unique() if "detector_params" in rows else []
    return f"{det} {params[0]}" if len(params) else det
