"""Which detector wins: ranks over cells, pairwise tests over blocks and seeds, mean figures.

Ranks and the critical-difference diagram follow the time-series classification literature
(Demšar 2006; Benavoli et al. 2016), with a protocol *cell* in the role of a dataset; the tests
are those of the intervals:

1. each detector's figure per cell is the mean over its seeds (``--repeats``);
2. only cells where every detector finished are ranked (a complete block design); the others
   are counted and reported as excluded;
3. per cell the detectors are ranked, 1 = best, ties sharing the mean rank
   (``scipy.stats.rankdata``); a detector's score in a scope is its mean rank over the scope's
   cells: per protocol, and over every cell at once (so a protocol weighs by its cell count);
4. one family of contrasts decides every pair, every group and the diagram's bars
   (:func:`pairwise`): each pair's mean difference over the scope's blocks with the interval the
   means take (over blocks and seeds, :func:`crossed_interval`), at one Bonferroni level over
   every scope's testable pairs (:func:`one_family`), read against the margin as every contrast
   is (:mod:`slipbench.stats.contrast`): shown ("yes") beyond it, contradicted ("no") inside
   it, else undecided. A pair is *decided* where its state is one of the first two
   (:data:`~slipbench.stats.contrast.DECIDED`), nowhere else. Detectors every pair of which is
   contradicted (shown within the margin) form a group, drawn as one bar; an undecided pair
   joins nothing. A pair of which an entrant ran one seed is not even *testable*: nothing
   measures the retraining luck its one run had in every block, and blocks alone called equal
   detectors different on 5 of 10 boards (issue 35); nor is a pair over one block, where
   nothing measures how the difference varies between conditions; both are undecided. So
   ranks, groups, pairwise table and diagram never disagree.

A block is counted once: cells that test the same model on the same test windows (the
sampling rate's full-rate cells are the window-size window-200 cells; with ``decimation=both``
three of them) are duplicates, found by the rows' model keys and test parts
(:func:`block_signature`), and merged into one block before anything is ranked, tested or
averaged. Blocks still share recordings (window 50 of one unit appears in several protocols,
each with another model or test set), so they are not independent: the intervals are
optimistic, and the report says so.

Without repeats each pair still shows its mean difference with a t-interval over blocks (how
the difference depends on which conditions make up the benchmark), undecided.

Mean accuracy, balanced accuracy and AUROC are over the same ranked cells, so they compare.
Their 95 % interval is a percentile bootstrap over cells (cells resampled, each cell's figure
fixed): it shows how the mean depends on which conditions make up the benchmark, not the test
noise within a cell, which the per-cell intervals show.

Seeds (``--repeats``). A block's figure is the mean over its seeds. Where some block holds
several seeds of an entrant, the seed is a factor of the design for the pairwise intervals and
the means' intervals too, and it is *crossed* with the blocks, not nested in them: a seed is one
split of the trials (streams ``sides``, ``split``) and one detector seed (stream ``detector``)
for every cell of a run, so its luck (a hard trial drawn into the test set, a lucky
initialisation) can reach every block at once and then does not average out over blocks.
Resampling blocks alone, or seeds within each block (a nested two-stage bootstrap), misses that
shared part. So blocks are resampled and, with one draw for every block, so are the seeds: the
variance is the sum of the two resamplings' variances (in closed form,
:func:`crossed_interval`), and the interval Banerjee's, each component with its own t quantile.

Measured (``benchmarks/bench_leaderboard_seeds.py``, 1,000 simulated boards per setting, two
equal detectors, 30 or 300 blocks, 2, 3 or 5 seeds; seed luck per block only, shared by the
blocks, both, or with the two detectors on different seeds; table in ``docs/studies/coverage.md``): the
pairwise interval excludes 0 on 0.2-4.9 % of boards with 3 or 5 seeds (2 seeds: 0.5-5.9 %),
where the percentile bootstrap over blocks does on 4-92 % (34-92 % wherever seed luck reaches
every block); the means' intervals cover 0.94-0.99 (blocks alone 0.29-0.84). Its width is 1.3-2.1
times that of an interval that knew the true spread with 3-5 seeds, 4-5 times with 2. Not
taken (exploratory, 2,000-3,000 boards per setting): subtracting the seed-by-block noise the
sum counts twice, with Welch-Satterthwaite degrees of freedom (an unbiased variance), excluded 0
on up to 11.5 % of boards with 3 seeds and 17 % with 2: the seed component has two degrees of
freedom, and a plug-in for them runs liberal; the sum with Welch-Satterthwaite degrees of
freedom, up to 7 % with 3 seeds; :func:`slipbench.stats.bootstrap.seeded_interval` with the
blocks as its clusters, 5.5-7.2 % with 3 seeds (600-1,500 boards). Without repeats the
percentile bootstrap over blocks stands as it was.

This module computes; the tables that show the leaderboard are the report wing's.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd
import scipy  # its submodules load on first use: reading stored rows pays none

from slipbench.seeding import rng_for
from slipbench.stats.contrast import (
    CONTRADICTED,
    SHOWN,
    family_level,
    from_parts,
    half_width,
    margin_of,
    p_beyond,
)
from slipbench.stats.factors import SETTINGS, entrant_names, factor_values, one_class
from slipbench.stats.noise import SeedNoise
from slipbench.store.columns import ACCURACY, WINDOWED, figures, recording
from slipbench.store.resolved import resolve

ALPHA = 0.05
LEVEL = 0.95
N_RESAMPLES = 2000
#: the margin within which a pair of the default figure reads "no difference"
MARGIN = margin_of(ACCURACY.name)
ALL = "all"
#: columns that, with the cell's key, name one cell across detectors: every setting of a run
#: (data, split, labels, options, ...) is part of it, so no block pools two values of one
CELL_IDENTITY = (*recording("protocol", "cell"), *SETTINGS)
#: columns that, with the model key, name the windows a cell is scored on
TEST_IDENTITY = recording("test", "stream")
#: the figures whose means the board shows: a windowed cell's, but the rates of one class
MEAN_METRICS = tuple(f.name for f in figures(WINDOWED) if not f.one_class)


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
    pairs : one row per pair (a ranked above b), :func:`pairwise`'s over the scope's blocks.
    groups : runs of entrants, in rank order, no two of which differ: the diagram's bars.
    """

    name: str
    n_cells: int
    n_excluded: int
    ranks: pd.Series
    wins: pd.Series
    pairs: pd.DataFrame
    groups: list[list[str]]
    n_duplicates: int = 0  # finished cells merged into a block another cell already stands for
    #: entrant -> ranked blocks where a cell it ran rests on few test trials (``low_n``)
    low_n: pd.Series = field(default_factory=lambda: pd.Series(dtype=int))


@dataclass
class Leaderboard:
    """Ranks, tests and mean figures of the detectors in a set of result rows.

    Attributes
    ----------
    metric : the figure ranked ("accuracy", ...).
    scopes : ``ALL`` first, then each protocol in the order given.
    means : entrant x (metric, "lo", "hi") over the ranked cells of ``ALL``: columns
        ``<m>``, ``<m>_lo``, ``<m>_hi`` for each of MEAN_METRICS, and ``<m>_cells`` (cells
        with a value: balanced accuracy and AUROC do not exist on a one-class test set); the
        constant answer's accuracy beside the detector's (:func:`_constant_means`).
    entrants : entrant -> the detector and parameters it stands for.
    pairs : :func:`pairwise` over the ranked blocks of ``ALL``.
    n_seeds : the most seeds an entrant ran in a ranked block; above 1, the pairs' and the
        means' intervals count seeds as a factor too (:func:`crossed_interval`).
    n_one_class : finished rows left out because their test set holds one class (a constant
        detector wins there: :func:`slipbench.stats.factors.one_class`).
    margin : the change within which a pair reads "no difference" (the metric's stored unit).
    level : the pairs' intervals' level, Bonferroni over every scope's testable pairs.
    low_n : entrant -> the ranked blocks of ``ALL`` where a cell it ran rests on few test
        trials (``low_n``): its figures there are not to be trusted, nor are means and ranks
        over them.
    """

    metric: str
    scopes: list[Scope]
    means: pd.DataFrame
    entrants: dict[str, str] = field(default_factory=dict)
    pairs: pd.DataFrame = field(default_factory=lambda: pairwise(pd.DataFrame(), []))
    n_seeds: int = 1
    n_one_class: int = 0
    margin: float = MARGIN
    level: float = LEVEL
    low_n: pd.Series = field(default_factory=lambda: pd.Series(dtype=int))

    @property
    def order(self) -> list[str]:
        """Entrants by overall mean rank, best first."""
        return list(self.scopes[0].ranks.index) if self.scopes else []

    def scope(self, name: str) -> Scope | None:
        return next((s for s in self.scopes if s.name == name), None)


#: the means' column of the constant answer's accuracy (:func:`constant_accuracy`)
CONSTANT = "constant_answer"


def constant_accuracy(rows: pd.DataFrame) -> pd.DataFrame:
    """Per row, the accuracy of the constant answer on its test set: "never slip" or "always
    slip", whichever scores more (the larger class's share of the test windows), and which
    (``never``: True where "never slip" scores at least as much). From the rows' test windows
    per class (``test_slip_windows``, ``test_nonslip_windows``), else from their confusion
    counts (slip windows ``tp + fn``, non-slip ``tn + fp``); NaN where a row holds neither.

    Returns
    -------
    DataFrame
        (n_rows, 2): ``accuracy`` (a fraction) and ``never`` (bool), on ``rows``' index.
    """

    def number(column: str) -> pd.Series:
        if column not in rows:
            return pd.Series(np.nan, index=rows.index)
        return pd.to_numeric(rows[column], errors="coerce").astype(float)

    slip, nonslip = number("test_slip_windows"), number("test_nonslip_windows")
    counted = number("tp") + number("fn"), number("tn") + number("fp")
    slip = slip.where(slip.notna() & nonslip.notna(), counted[0])
    nonslip = nonslip.where(nonslip.notna(), counted[1])
    total = slip + nonslip
    best = np.maximum(slip, nonslip) / total.where(total > 0)
    return pd.DataFrame({"accuracy": best, "never": nonslip >= slip}, index=rows.index)


def entrants(rows: pd.DataFrame) -> pd.Series:
    """Who competes: the detector's id, named apart where its rows differ in what it is or reads
    (:func:`slipbench.stats.factors.entrant_names`: ``holweg (band=[39, 100])``)."""
    return entrant_names(rows)


def _identity(rows: pd.DataFrame) -> pd.DataFrame:
    """The cell identity of each row (:data:`CELL_IDENTITY`, the columns the rows hold), as
    text: a setting a row lacks reads as its default, so older rows still meet newer ones."""
    return pd.DataFrame(
        {c: factor_values(rows, c) for c in CELL_IDENTITY if c in rows}, index=rows.index
    )


def cell_table(rows: pd.DataFrame, metric: str) -> pd.DataFrame:
    """(n_cells, n_entrants) figure per cell: the mean over seeds of the ok rows; NaN where an
    entrant has no finished row of the cell. Index: the cell identity columns the rows hold."""
    frame = _identity(rows)
    ident = list(frame.columns)
    frame["_entrant"] = entrants(rows)
    ok = frame[rows["status"] == "ok"] if "status" in rows else frame
    ok = ok.assign(_value=pd.to_numeric(rows.loc[ok.index].get(metric), errors="coerce"))
    table = (
        ok.groupby([*ident, "_entrant"], sort=False, dropna=False)["_value"]
        .mean()
        .unstack("_entrant")
    )
    cells = frame[ident].drop_duplicates().set_index(ident).index
    return table.reindex(index=cells, columns=frame["_entrant"].unique())


def block_signature(rows: pd.DataFrame) -> pd.Series:
    """Per cell (the index of :func:`cell_table`): what it measures, as one hashable value.

    Two cells measure the same thing when every row of one has a row of the other with the
    same model key (data, split, seed, detector, training windows, window, rate) and the same
    test part (sensors, filters, streaming or not): the same model on the same test windows.
    A cell some row of which lacks its model key (rows of an old version) is its own block.
    """
    if rows.empty:
        return pd.Series(dtype=object)
    identity = _identity(rows)
    ident = list(identity.columns)
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
    for cell, group in parts.join(identity).groupby(ident, sort=False, dropna=False):
        cell = cell if isinstance(cell, tuple) else (cell,)
        out[cell] = tuple(sorted(set(group["_sig"]))) if group["_known"].all() else ("cell", *cell)
    index = pd.MultiIndex.from_tuples(list(out), names=ident)
    return pd.Series(list(out.values()), index=index, dtype=object)


def _signatures(index: pd.Index, signature: pd.Series) -> list[tuple]:
    """Each cell's signature; a cell the signature does not know (no rows of it): its own."""
    sig = signature.reindex(index)
    return [s if isinstance(s, tuple) else ("cell", *i) for i, s in zip(index, sig)]


def merge_blocks(table: pd.DataFrame, signature: pd.Series) -> tuple[pd.DataFrame, int]:
    """``table`` (cells x entrants) with duplicate cells merged: one line per block, at its first
    cell, each entrant's figure the mean over the block's cells that hold one (the same model
    on the same windows: equal where both finished). Returns the blocks and how many finished
    cells were merged into a block another cell already stood for."""
    if table.empty:
        return table, 0
    codes = pd.Series(
        pd.factorize(pd.Series(_signatures(table.index, signature)))[0], index=table.index
    )
    first = ~codes.duplicated()
    merged = table.groupby(codes.to_numpy(), sort=False).mean()
    merged.index = table.index[first.to_numpy()]
    complete = table.notna().all(axis=1)
    n_dup = int(complete.sum()) - int(
        merged.notna().all(axis=1).reindex(table.index[first.to_numpy()]).sum()
    )
    return merged, max(n_dup, 0)


def seed_values(
    rows: pd.DataFrame, metric: str, blocks: pd.Index, signature: pd.Series
) -> dict[str, np.ndarray]:
    """Per entrant, its figure in each block of ``blocks`` (the index :func:`merge_blocks` gives)
    under each seed: an array (n_blocks, n_seeds) over the seeds the rows hold (sorted), NaN
    where the entrant has no finished row of the block under that seed; a block of duplicate
    cells takes their mean per seed, as :func:`merge_blocks` does over seeds' means."""
    ok = rows[rows["status"] == "ok"] if "status" in rows else rows
    identity = _identity(ok)
    ident = list(identity.columns)
    who = entrants(rows)
    seeds = ok["seed"] if "seed" in ok else pd.Series(0, index=ok.index)
    levels = sorted(seeds.dropna().unique())
    position = {sig: i for i, sig in enumerate(_signatures(blocks, signature))}
    cells = (
        pd.MultiIndex.from_frame(identity)
        if len(ok)
        else pd.MultiIndex.from_tuples([], names=ident)
    )
    block = [position.get(sig, -1) for sig in _signatures(cells, signature)]
    frame = pd.DataFrame(
        {
            "block": block,
            "seed": seeds.map({s: i for i, s in enumerate(levels)}).to_numpy(),
            "entrant": who.loc[ok.index].to_numpy(),
            "value": (
                pd.to_numeric(ok[metric], errors="coerce").to_numpy(dtype=float)
                if metric in ok
                else np.full(len(ok), np.nan)
            ),
        }
    )
    frame = frame[(frame["block"] >= 0) & frame["value"].notna()]
    out = {}
    for e in who.unique():
        values = np.full((len(blocks), max(len(levels), 1)), np.nan)
        mine = frame[frame["entrant"] == e].groupby(["block", "seed"])["value"].mean()
        if len(mine):
            b, k = (mine.index.get_level_values(i).to_numpy(dtype=int) for i in (0, 1))
            values[b, k] = mine.to_numpy()
        out[e] = values
    return out


@dataclass(frozen=True)
class Crossed:
    """A figure over blocks and seeds, its variance components and its interval
    (:func:`crossed_interval`).

    Attributes
    ----------
    estimate : the figure (mean over blocks of the seeds' mean, or a difference of two).
    parts : (variance, degrees of freedom) per component: the blocks' first, then each side's
        seeds (sides of one seed have none).
    """

    estimate: float
    parts: tuple[tuple[float, float], ...]

    def half_width(self, level: float = LEVEL) -> float:
        """Banerjee's half-width (:func:`slipbench.stats.contrast.half_width`): never narrower
        than the interval of the component with the fewest degrees of freedom alone, whatever
        the true ratio of the components (Banerjee 1961), where Welch-Satterthwaite's plug-in
        degrees of freedom run liberal with a component of 1-4."""
        return half_width(self.parts, level)


def _filled(values: np.ndarray) -> np.ndarray:
    """A side's (n_blocks, n_seeds) figures over the seeds it ran (columns it never ran left
    out), a block's missing seed filled with the block's mean over its other seeds: the block's
    figure stays as it is, and the gap adds no seed-to-seed spread."""
    values = values[:, np.isfinite(values).any(axis=0)]
    mean = np.nanmean(values, axis=1, keepdims=True)
    return np.where(np.isfinite(values), values, mean)


def crossed_interval(sides: list[np.ndarray], signs: tuple[float, ...]) -> Crossed:
    """``sum_k signs[k] * (mean over blocks of side k's mean over its seeds)`` with the variance
    components of the crossed bootstrap of blocks and seeds (module docstring), in closed form.

    The blocks' component is the variance over blocks of the block's figure (its signed sum of
    the sides' seed means) over the number of blocks, ``B - 1`` degrees of freedom: what
    resampling blocks gives. Each side's seed component is the variance over its seeds of the
    seed's mean over blocks over the number of seeds, ``S_k - 1`` degrees of freedom: what
    resampling the seeds, one draw for every block, gives. Their sum is the "pigeonhole"
    variance of crossed designs (Owen 2007): it counts the seed-by-block noise twice, so it errs
    wide (subtracting it once leaves a difference of mean squares whose plug-in degrees of
    freedom undercovered: ``benchmarks/bench_leaderboard_seeds.py``). The interval is
    Banerjee's (:meth:`Crossed.half_width`).

    Parameters
    ----------
    sides : list of ndarray of shape (n_blocks, n_seeds_k)
        Per side, each block's figure under each seed (NaN: not run; :func:`_filled`). Pass one
        side of differences, seed by seed, where both entrants ran the same seeds.
    signs : per side, its weight: ``(1,)`` for a mean or paired differences, ``(1, -1)`` for A - B.
    """
    filled = [_filled(x) for x in sides]
    per_block = sum(k * x.mean(axis=1) for k, x in zip(signs, filled))
    n_blocks = len(per_block)
    parts = [(float(np.var(per_block, ddof=1)) / n_blocks, n_blocks - 1.0)]
    for k, x in zip(signs, filled):
        if x.shape[1] > 1:
            parts.append(
                (k**2 * float(np.var(x.mean(axis=0), ddof=1)) / x.shape[1], x.shape[1] - 1.0)
            )
    return Crossed(float(np.mean(per_block)), tuple(parts))


#: why a pair is undecided without a full interval
ONE_BLOCK = "one block: how the difference varies between conditions is not measured"
ONE_RUN = (
    "an entrant ran one seed, so nothing measures the luck its one run had in every block "
    "(run `evaluate --repeats 2` or more)"
)
#: the pairs' columns: the contrast of A - B, its interval at ``level`` (the family's
#: Bonferroni level), its state and, where undecided, why; ``p``: the Bonferroni-adjusted
#: p-value of a change within the margin (:func:`slipbench.stats.contrast.p_beyond`), below
#: ``ALPHA`` exactly where the pair differs; ``testable``: its interval holds every noise the
#: claim needs (it counts in the Bonferroni family); ``decided``: its state settles it (shown
#: or contradicted, :func:`slipbench.stats.contrast.is_decided`); ``parts``/``missing``: what
#: :func:`at_level` draws it from
PAIR_COLUMNS = [
    "a",
    "b",
    "diff",
    "lo",
    "hi",
    "se",
    "df",
    "level",
    "p",
    "state",
    "why",
    "testable",
    "decided",
    "differ",
    "parts",
    "missing",
]


def pair_parts(
    a: np.ndarray, b: np.ndarray, noise: SeedNoise | None = None
) -> tuple[float, tuple[tuple[float, float], ...], str]:
    """A - B over blocks and seeds (each (n_blocks, n_seeds), NaN where not run):
    :func:`crossed_interval`'s estimate and variance parts, paired seed by seed where the two
    ran the same seeds of every block, and the noise the pair lacks ("" where none): one block
    leaves the blocks' part unmeasured, an entrant of one seed its seeds' part, which
    ``noise`` (a seed variance from elsewhere, :class:`~slipbench.stats.noise.SeedNoise`) then
    stands for."""
    paired = np.array_equal(np.isfinite(a), np.isfinite(b))
    sides, signs = ([a - b], (1.0,)) if paired else ([a, b], (1.0, -1.0))
    filled = [_filled(x) for x in sides]
    per_block = sum(k * x.mean(axis=1) for k, x in zip(signs, filled))
    n_blocks = len(per_block)
    parts, missing = [], []
    if n_blocks > 1:
        parts.append((float(np.var(per_block, ddof=1)) / n_blocks, n_blocks - 1.0))
    else:
        missing.append(ONE_BLOCK)
    for k, x in zip(signs, filled):
        n_seeds = x.shape[1]
        if n_seeds > 1:
            parts.append((k**2 * float(np.var(x.mean(axis=0), ddof=1)) / n_seeds, n_seeds - 1.0))
        elif noise is not None:
            parts.append((k**2 * noise.of_mean(n_seeds), noise.df))
        elif ONE_RUN not in missing:
            missing.append(ONE_RUN)
    return float(np.mean(per_block)), tuple(parts), "; ".join(missing)


def pairwise(
    blocks: pd.DataFrame,
    order: list[str],
    seeds: dict[str, np.ndarray] | None = None,
    noise: SeedNoise | None = None,
    margin: float = MARGIN,
) -> pd.DataFrame:
    """Every pair (a ranked above b): the contrast of a - b over the complete ``blocks`` and
    the seeds (``seeds``: :func:`seed_values` over ``blocks``' index; None: one seed each),
    :func:`pair_parts`, with its interval and state against ``margin`` at the Bonferroni level
    over the pairs that can decide (:func:`at_level`). A pair of one block, or of an entrant of
    one seed (without ``noise``), is undecided: it never differs, never reads "no".

    Columns: :data:`PAIR_COLUMNS`.
    """
    complete = blocks[order].dropna() if len(order) else blocks.iloc[:0]
    if len(complete) == 0 or len(order) < 2:
        return pd.DataFrame(columns=PAIR_COLUMNS)
    at = blocks.index.get_indexer(complete.index)
    per_seed = {
        e: seeds[e][at] if seeds is not None else complete[e].to_numpy(float)[:, None]
        for e in order
    }
    lines = []
    for i, a in enumerate(order):
        for b in order[i + 1 :]:
            diff, parts, missing = pair_parts(per_seed[a], per_seed[b], noise)
            lines.append({"a": a, "b": b, "diff": diff, "parts": parts, "missing": missing})
    pairs = pd.DataFrame(lines)
    at_level([pairs], margin)
    return pairs[PAIR_COLUMNS]


def at_level(frames: list[pd.DataFrame], margin: float = MARGIN) -> float:
    """The pairs of ``frames`` (in place) with their intervals, states and adjusted p-values
    at one Bonferroni level over every distinct pair that can decide (no noise missing; a
    scope of the same blocks as another, one protocol's and every cell's, repeats its tests
    and is counted once): the level holds ``ALPHA`` for the family. An interval is clipped to
    what a difference of two fractions can be, ±1 (its state is not moved by it). Returns the
    level."""
    tests = {
        (a, b, d, parts)
        for f in frames
        if len(f)
        for a, b, d, parts, missing in zip(f["a"], f["b"], f["diff"], f["parts"], f["missing"])
        if not missing
    }
    m = len(tests)
    level = family_level(m, ALPHA)
    for f in frames:
        if not len(f):
            continue
        shown = [
            replace(from_parts(d, parts, level, margin), missing=missing)
            for d, parts, missing in zip(f["diff"], f["parts"], f["missing"])
        ]
        f["lo"], f["hi"] = [max(c.lo, -1.0) for c in shown], [min(c.hi, 1.0) for c in shown]
        f["se"], f["df"] = [c.se for c in shown], [c.df for c in shown]
        f["level"], f["state"], f["why"] = level, [c.state for c in shown], [c.why for c in shown]
        f["testable"] = [not c.missing and c.judged for c in shown]
        f["decided"] = [c.decided for c in shown]
        f["p"] = [
            min(1.0, m * p_beyond(d, parts, margin)) if ok else np.nan
            for d, parts, ok in zip(f["diff"], f["parts"], f["testable"])
        ]
        f["differ"] = f["state"] == SHOWN
    return level


def _groups(order: list[str], pairs: pd.DataFrame) -> list[list[str]]:
    """Maximal runs of rank-ordered entrants every pair of which is contradicted (its interval
    inside the margin): the diagram's bars. An undecided pair joins no group, whatever it lacks
    (a noise, or an interval narrow enough): nothing says its two do not differ."""
    joined = {
        (a, b)
        for a, b, state in pairs[["a", "b", "state"]].itertuples(index=False)
        if state == CONTRADICTED
    }
    runs: list[tuple[int, int]] = []  # (first, last) positions in ``order``
    for i in range(len(order)):
        j = i
        while j + 1 < len(order) and all(
            (order[k], order[j + 1]) in joined for k in range(i, j + 1)
        ):
            j += 1
        if j > i and not any(s <= i and j <= e for s, e in runs):
            runs.append((i, j))
    return [order[s : e + 1] for s, e in runs]


def rank_scope(
    scores: pd.DataFrame,
    name: str,
    seeds: dict[str, np.ndarray] | None = None,
    noise: SeedNoise | None = None,
    margin: float = MARGIN,
) -> Scope:
    """Rank the entrants (columns) over the complete cells (rows) of ``scores``; the pairs and
    groups from :func:`pairwise` (``seeds``: :func:`seed_values` over ``scores``' index)."""
    complete = scores.dropna()
    n_excluded = len(scores) - len(complete)
    if complete.empty or scores.shape[1] == 0:
        empty = pd.Series(dtype=float)
        return Scope(name, 0, n_excluded, empty, empty, pairwise(complete, []), [])
    ranks = pd.DataFrame(
        scipy.stats.rankdata(-complete.to_numpy(), axis=1),
        index=complete.index,
        columns=complete.columns,
    )
    mean = ranks.mean().sort_values(kind="stable")
    order = list(mean.index)
    wins = (ranks == ranks.min(axis=1).to_numpy()[:, None]).sum()[order]
    pairs = pairwise(scores, order, seeds, noise, margin)
    return Scope(name, len(complete), n_excluded, mean, wins, pairs, _groups(order, pairs))


def one_family(scopes: list[Scope], margin: float = MARGIN) -> float:
    """One Bonferroni level across the pairs of every scope that can decide (in place): a
    leaderboard is one family, so equal detectors differ in some scope on at most ``ALPHA`` of
    boards (each scope its own family let 3 scopes of 3 equal entrants differ on 12.7 % of
    boards, ``benchmarks/bench_leaderboard_null.py``); intervals, states and groups follow.
    Returns the level."""
    level = at_level([s.pairs for s in scopes], margin)
    for s in scopes:
        s.groups = _groups(list(s.ranks.index), s.pairs)
    return level


def _mean_interval(
    values: np.ndarray, per_seed: np.ndarray | None = None, seed: int = 0
) -> tuple[float, float, float]:
    """The mean of the finite values (blocks' figures) and its percentile bootstrap interval
    over them; with ``per_seed`` (the blocks' figures per seed, (n_blocks, n_seeds)) holding
    several seeds of a block, :func:`crossed_interval` over blocks and seeds (clipped to
    [0, 1])."""
    if per_seed is not None and (np.isfinite(per_seed).sum(axis=1) > 1).any():
        kept = np.isfinite(values)
        if kept.sum() >= 2:
            iv = crossed_interval([per_seed[kept]], (1.0,))
            half = iv.half_width()
            return iv.estimate, max(iv.estimate - half, 0.0), min(iv.estimate + half, 1.0)
    values = values[np.isfinite(values)]
    if len(values) < 2:
        return (float(values[0]) if len(values) else np.nan), np.nan, np.nan
    if np.all(
        values == values[0]
    ):  # nothing to resample; scipy would warn of a degenerate distribution
        return float(values[0]), float(values[0]), float(values[0])
    res = scipy.stats.bootstrap(
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
    rows: pd.DataFrame,
    metric: str = ACCURACY.name,
    protocols: list[str] | None = None,
    noise: SeedNoise | None = None,
) -> Leaderboard:
    """Rank the detectors in ``rows`` (result rows of one or more detectors) by ``metric``.

    Parameters
    ----------
    rows : result rows as ``evaluate`` writes them (any statuses; only "ok" rows count, and of
        them not those tested on one class, where always saying "slip" would win).
    metric : the figure ranked; higher is better.
    protocols : the per-protocol scopes, in order (default: as the rows first name them).
    noise : a seed variance from elsewhere (a calibration of the bench) that decides pairs
        whose entrants ran one seed (:func:`pair_parts`).
    """
    margin = margin_of(metric)
    rows = resolve(rows).rows  # resolved once: the steps below read its entrants and cells
    lone = one_class(rows)
    rows = rows[~lone]
    who = entrants(rows)
    names = {e: _params_text(rows.loc[who == e]) for e in who.unique()}
    protocols = list(dict.fromkeys(rows["protocol"])) if protocols is None else protocols
    table = cell_table(rows, metric)
    signature = block_signature(rows)

    low = merge_blocks(cell_table(rows, "low_n"), signature)[0] > 0

    def scope(part: pd.DataFrame, name: str) -> tuple[Scope, pd.DataFrame]:
        blocks, n_dup = merge_blocks(part, signature)
        per_seed = seed_values(rows, metric, blocks.index, signature)
        ranked = rank_scope(blocks, name, per_seed, noise, margin)
        ranked.n_duplicates = n_dup
        mine = low.reindex(index=blocks.dropna().index, columns=ranked.ranks.index)
        ranked.low_n = mine.fillna(False).sum().astype(int)
        return ranked, blocks

    overall, blocks = scope(table, ALL)
    scopes = [overall]
    for protocol in protocols:
        part = table[table.index.get_level_values("protocol") == protocol]
        if len(part):
            scopes.append(scope(part, protocol)[0])
    level = one_family(scopes, margin)
    ranked = blocks.dropna().index
    means = pd.DataFrame(index=pd.Index(overall.ranks.index, name=None))
    n_seeds = 1
    for m in MEAN_METRICS:
        values = (
            merge_blocks(cell_table(rows, m), signature)[0].reindex(ranked)
            if m != metric
            else blocks.reindex(ranked)
        )
        seeds = seed_values(rows, m, ranked, signature)
        for e in means.index:
            x = values[e].to_numpy(dtype=float)
            means.loc[e, [m, f"{m}_lo", f"{m}_hi"]] = _mean_interval(x, seeds[e])
            means.loc[e, f"{m}_cells"] = int(np.isfinite(x).sum())
            n_seeds = max(n_seeds, int(np.isfinite(seeds[e]).sum(axis=1).max(initial=1)))
    _constant_means(means, rows, ranked, signature)
    return Leaderboard(
        metric,
        scopes,
        means,
        names,
        overall.pairs,
        n_seeds,
        int(lone.sum()),
        margin,
        level,
        overall.low_n,
    )


def _constant_means(
    means: pd.DataFrame, rows: pd.DataFrame, ranked: pd.Index, signature: pd.Series
) -> None:
    """``means`` (in place) with the constant answer beside the accuracy: per entrant, over
    the ranked blocks where both its accuracy and the constant's are known, the mean of each
    (``constant_answer``, ``constant_accuracy``: the same blocks, so they compare), how many
    blocks (``constant_cells``) and in how many of them "never slip" was the constant answer
    (``constant_never``)."""
    answer = constant_accuracy(rows)
    with_answer = rows.assign(_constant=answer["accuracy"], _never=answer["never"].astype(float))
    value = merge_blocks(cell_table(with_answer, "_constant"), signature)[0].reindex(ranked)
    never = merge_blocks(cell_table(with_answer, "_never"), signature)[0].reindex(ranked)
    accuracy = merge_blocks(cell_table(rows, ACCURACY.name), signature)[0].reindex(ranked)
    for e in means.index:
        c = value[e].to_numpy(float) if e in value else np.full(len(ranked), np.nan)
        a = accuracy[e].to_numpy(float) if e in accuracy else np.full(len(ranked), np.nan)
        both = np.isfinite(c) & np.isfinite(a)
        n = int(both.sum())
        means.loc[e, CONSTANT] = float(c[both].mean()) if n else np.nan
        means.loc[e, "constant_accuracy"] = float(a[both].mean()) if n else np.nan
        means.loc[e, "constant_cells"] = n
        means.loc[e, "constant_never"] = int((never[e].to_numpy(float)[both] >= 0.5).sum())


def _params_text(rows: pd.DataFrame) -> str:
    det = str(rows["detector"].iloc[0])
    params = rows["detector_params"].dropna().unique() if "detector_params" in rows else []
    return f"{det} {params[0]}" if len(params) else det
