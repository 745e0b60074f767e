"""Steps in a history's series: proposed by binary segmentation, confirmed by the gate's test.

*Proposed.* Each series' points over runs (:func:`slipbench.history.coded.points`, one per run,
oldest first) are cut by binary segmentation (ruptures' ``Binseg``, its breakpoints made in numpy:
:func:`slipbench.history.segmentation.weighted_binseg`) under a cost that weighs every point by
its interval: the precision-weighted squared error about each segment's weighted mean (asv
weighs its steps the same way). The intervals hold a run's
test-set noise and, where it ran several seeds, their spread; where the series moves more
from run to run than they say (seeds that change splits), the robust spread of its successive
differences scales the penalty, never below what the intervals say. The penalty is
``PENALTY * scale * log(points)``: a BIC-like price per cut.

*Confirmed.* A proposal is a step only where the gate would call it one: the runs of the
segment before and of the segment after (up to the neighbouring proposals) are its two sides,
each segment's results its seeds (a result a later run kept, with the same code and seed,
counts once), and :func:`step_change` gives the change as the gate's one contrast
(:mod:`slipbench.stats.contrast`): its estimate, standard error, degrees of freedom, interval
and state against the figure's tolerance in the gate (its margin). Bonferroni holds each
series' proposals at ``SERIES_ALPHA`` (:func:`~slipbench.stats.contrast.family_level`), and the
interval shown is the one the verdict read: a step is *regressed* or *improved* where that
interval lies beyond the tolerance (the contrast's state ``shown``), else *not confirmed*;
proposals with one seed on each side (no retraining noise measured) or in low-n cells (fewer
than ``LOW_N`` test trials of a class) are *inconclusive*.

The gate's windowed figures (accuracy, TN rate, TP rate) are judged, per cell and pooled over
a protocol's cells; streaming series are kept and plotted, and judged once compare judges
streams of several seeds a side.
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from slipbench.gate.gate import Gate, needed, resolution, scaled_resolution
from slipbench.history.coded import KINDS, Coded, FigureRows, categorical
from slipbench.history.coded import figure_rows as coded_rows
from slipbench.history.coded import points as coded_points
from slipbench.history.judging import SEGMENT_SEEDS, SERIES_ALPHA, Side, judge
from slipbench.history.segmentation import weighted_binseg
from slipbench.history.series import POOL
from slipbench.history.short import FEWEST, LONG, SHORT, short_change
from slipbench.history.short import scale as short_scale
from slipbench.stats.contrast import (
    ONE_SEED,
    SHOWN,
    TEST_NOISE,
    Contrast,
    from_parts,
    p_beyond,
)
from slipbench.stats.noise import SeedNoise, pool_seed_spreads
from slipbench.store.columns import FIGURES, WINDOWED, names

#: the price of a cut, times the series' noise scale and log(points)
PENALTY = 6.0
#: the figures judged: the windowed figures the gate reads
JUDGED = names(WINDOWED, gated=True)
#: the fewest runs a segment holds
MIN_RUNS = 4
#: what a step's run may have changed against the run before, and the column that says so
CAUSES = (
    ("code", "code_identity"),
    ("parameters", "detector_params"),
    ("dataset", "dataset_fingerprint"),
    ("bench file", "bench_digest"),
)
#: the history's columns :func:`find_steps` reads (``read_history(..., STEP_COLUMNS)``)
STEP_COLUMNS = [
    "series",
    "series_label",
    "key",
    "seed",
    "status",
    "low_n",
    "df",
    *POOL,  # what labels and pools a step's series
    "cell",
    "proven",
    *(c for _, c in CAUSES),
    *(f"{f}{end}" for f in JUDGED for end in ("", "_se")),
]
#: points per worker process below which the series are cut in this process (starting the
#: workers costs more than cutting; benchmarks/bench_history.py)
POINTS_PER_WORKER = 200_000


def noise_scale(value: np.ndarray, se: np.ndarray) -> float:
    """How much more a series moves from run to run than its intervals say: the squared
    robust (MAD) spread of its successive differences in units of their standard errors,
    at least 1."""
    if len(value) < 3:
        return 1.0
    z = np.diff(value) / np.sqrt(se[1:] ** 2 + se[:-1] ** 2)
    mad = 1.4826 * float(np.median(np.abs(z - np.median(z))))
    return max(1.0, mad**2)


def propose(value: np.ndarray, se: np.ndarray) -> list[int]:
    """The indices where a new segment starts (none: no step proposed), from binary
    segmentation under the weighted cost with the penalty of the module's docstring."""
    n = len(value)
    if n < 2 * MIN_RUNS:
        return []
    floor = np.nanmedian(se[se > 0]) if np.any(se > 0) else 1.0
    se = np.where(np.isfinite(se) & (se > 0), se, floor)  # a point without spread: the median's
    pen = PENALTY * noise_scale(value, se) * math.log(n)
    return weighted_binseg(value, 1.0 / se**2, pen, MIN_RUNS)


def step_change(
    sides: tuple[list[dict], list[dict]],
    figure: str,
    level: float,
    margin: float,
) -> Contrast:
    """The change of ``figure`` from the seeds before a step to those after it (``sides``, each
    seed a row with the figure, its ``_se`` and ``df``) as a contrast (:mod:`slipbench.stats.contrast`) at
    ``level`` against ``margin`` (both in the figure's stored unit): the difference of the
    segments' means, its variance the seed variance over the seeds of each side.

    The seed variance is the segments' own spread pooled over both (a step moves the figure,
    not the bench's seed noise) on ``seeds - 2`` degrees of freedom: a seed's value differs from another's by its
    training and, where seeds draw the split, its test trials, so that spread holds both.
    Where each side holds one seed, nothing measures retraining
    noise: the interval holds both rows' test-set noise, and the contrast says what it lacks
    (``missing``), so it stays undecided.
    """
    before, after = sides
    b, a = (np.array([r[figure] for r in side], float) for side in sides)
    estimate = float(a.mean() - b.mean())
    own = pool_seed_spreads(
        (float(np.var(v, ddof=1)) if len(v) > 1 else np.nan, len(v)) for v in (b, a)
    )
    seeds = own and SeedNoise(own.variance, own.df, SEGMENT_SEEDS)
    if seeds is None:
        test = sum(float(r[f"{figure}_se"]) ** 2 for r in (before[0], after[0]))
        df = min(float(r["df"]) for r in (before[0], after[0]))
        alone = from_parts(estimate, [(test, df)], level, margin)
        return replace(alone, missing=ONE_SEED, noise=(TEST_NOISE,))
    parts = [(seeds.of_mean(len(b)) + seeds.of_mean(len(a)), seeds.df)]
    return replace(from_parts(estimate, parts, level, margin), noise=(seeds.source,))


@dataclass
class Steps:
    """What :func:`find_steps` found: one row per proposal (``steps``), the history it read."""

    steps: pd.DataFrame
    runs: pd.DataFrame  # one row per run, oldest first: commit, date, machine, bench_digest
    series: int  # series searched (cell and pooled, over the judged figures)
    # every series' points: series, series_label, figure, kind, run, value, se
    points: pd.DataFrame = field(default_factory=pd.DataFrame)
    gate: Gate = field(default_factory=Gate)

    @property
    def confirmed(self) -> pd.DataFrame:
        return self.steps[self.steps["verdict"].isin(["regressed", "improved"])]


def _cut(batch: list[tuple[np.ndarray, np.ndarray]]) -> list[list[int]]:
    return [propose(v, s) for v, s in batch]


def _proposals(work: list[tuple[np.ndarray, np.ndarray]], jobs: int) -> list[list[int]]:
    """Binseg over every series (values, standard errors), in ``jobs`` processes where the
    points are many enough."""
    size = sum(len(v) for v, _ in work)
    workers = max(1, min(jobs, size // POINTS_PER_WORKER))
    if workers == 1:
        return _cut(work)
    chunks = [work[i::workers] for i in range(workers)]
    with ProcessPoolExecutor(workers) as pool:
        done = list(pool.map(_cut, chunks))
    out: list[list[int]] = [[] for _ in work]
    for i, found in enumerate(done):
        out[i::workers] = found
    return out


def _runs(frame: pd.DataFrame) -> pd.DataFrame:
    """One row per run: its commit, date, machine, bench file, and its rows that entered the
    history unproven (``unproven``: no digest vouched for them)."""
    runs = frame.groupby("run", sort=True)[["commit", "date", "machine", "bench_digest"]].first()
    for c in runs:  # read as categoricals: text again, one value per run
        if isinstance(runs[c].dtype, pd.CategoricalDtype):
            runs[c] = runs[c].astype("str")
    proven = frame["proven"] if "proven" in frame else pd.Series(True, index=frame.index)
    runs["unproven"] = (~proven.fillna(False).astype(bool)).groupby(frame["run"]).sum()
    return runs.reset_index()


def _verdict(change: Contrast, figure: str, low_n: bool, proposals: int) -> dict:
    """A proposal's change in the figure's change unit (its interval the one its state read)
    and its verdict; ``p_adjusted``: Bonferroni's p of a change within the tolerance (below
    ``SERIES_ALPHA`` exactly where the interval is shown beyond it), for ordering."""
    declared = FIGURES[figure]
    shown = change.scaled(declared.scale)
    p = p_beyond(change.estimate, [(change.se**2, change.df)], change.margin)
    if low_n or change.missing:
        verdict, why = "inconclusive", "low n" if low_n else change.missing
    elif change.state == SHOWN:
        verdict, why = ("regressed" if change.direction == declared.worse else "improved"), ""
    else:
        verdict, why = "not confirmed", change.why
    return {
        "change": shown.estimate,
        "change_lo": shown.lo,
        "change_hi": shown.hi,
        "se": shown.se,
        "df": shown.df,
        "level": shown.level,
        "tolerance": shown.margin,
        "p_adjusted": min(1.0, proposals * p) if not (low_n or change.missing) else 1.0,
        "noise": ", ".join(change.noise),
        "verdict": verdict,
        "why": why,
    }


def _runs_needed(change: Contrast, proposals: int, seeds: int) -> int:
    """The fewest seeds (runs of one seed) a side at which a change as large as this one,
    measured with this spread, is confirmed with the gate's power (:func:`slipbench.gate.gate.needed`,
    80 %): what would decide a proposal left unconfirmed. 0 where it is confirmed, cannot be
    measured, or lies within the tolerance (no number of runs shows it beyond)."""
    beyond = abs(change.estimate) - change.margin
    if change.state == SHOWN or change.missing or not (beyond > 0 and change.se > 0):
        return 0

    def resolve(se: float, df: float) -> float:
        return resolution(se, df, proposals, SERIES_ALPHA)

    return needed(seeds, beyond, scaled_resolution(seeds, change.se, change.df, True, resolve))


_COLUMNS = {
    "series": str,
    "series_label": str,
    "kind": str,
    "figure": str,
    "run": int,
    "previous_run": int,
    "runs_before": int,
    "runs_after": int,
    "first_run": int,
    "last_run": int,
    "seeds_before": int,
    "seeds_after": int,
    "low_n": bool,
    "change": float,
    "change_lo": float,
    "change_hi": float,
    "se": float,
    "df": float,
    "level": float,
    "tolerance": float,
    "p_adjusted": float,
    "noise": str,
    "verdict": str,
    "why": str,
    "what_changed": str,
    "runs_needed": int,
    "route": str,
}


def _series_slices(codes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows grouped by code (stable: each group in the rows' order) and each code's start."""
    order = np.argsort(codes, kind="stable")
    starts = np.searchsorted(codes[order], np.arange(int(codes.max(initial=-1)) + 2))
    return order, starts


class _Causes:
    """What each run changed, read from the history's rows as codes: per cell series its own
    rows (:func:`_what_changed`), per pooled series every row of the two runs."""

    def __init__(self, frame: pd.DataFrame, coded: Coded) -> None:
        self.codes = [_codes_of(frame[c]) for _, c in CAUSES]
        self.run = coded.run
        self.by_series = _series_slices(coded.series)
        self.by_run = _series_slices(coded.run)
        self.cells = len(coded.names)
        self._runs: dict[int, list[frozenset]] = {}

    def _of_run(self, run: int) -> list[frozenset]:
        if run not in self._runs:
            order, starts = self.by_run
            rows = order[starts[run] : starts[run + 1]]
            self._runs[run] = [frozenset(c[rows].tolist()) for c in self.codes]
        return self._runs[run]

    def between(self, series: int, before: int, after: int) -> str:
        """What run ``after`` changed against run ``before`` in the series (code ``series``)."""
        if series < self.cells:
            order, starts = self.by_series
            rows = order[starts[series] : starts[series + 1]]
            runs = self.run[rows]
            a, b = rows[runs == before], rows[runs == after]
            differ = [set(c[a].tolist()) != set(c[b].tolist()) for c in self.codes]
        else:
            differ = [x != y for x, y in zip(self._of_run(before), self._of_run(after))]
        return ", ".join(name for (name, _), d in zip(CAUSES, differ) if d) or "seeds only"


def _codes_of(column: pd.Series) -> np.ndarray:
    """A cause column's values as codes of their text (``str``, as the causes compare them)."""
    if isinstance(column.dtype, pd.CategoricalDtype):  # its own codes; -1 (missing) the last
        uniques = [*column.cat.categories, np.nan]
        texts = pd.factorize(np.array([str(u) for u in uniques], dtype=object))[0]
        return texts[column.cat.codes.to_numpy()]
    codes, uniques = pd.factorize(column, use_na_sentinel=False)
    texts = pd.factorize(np.array([str(u) for u in uniques], dtype=object))[0]
    return texts[codes]


def find_steps(frame: pd.DataFrame, gate: Gate | None = None, jobs: int = 1) -> Steps:
    """Propose and confirm the steps of every judged series of a history (module docstring).

    Parameters
    ----------
    frame : history rows with their ``run`` (:func:`slipbench.store.history.read_history`).
    gate : the figures judged and their tolerances (default: the gate's windowed figures).
    jobs : processes that cut the series (used where the points are many).
    """
    gate = gate or Gate()
    figures = [f for f in JUDGED if f in gate.tolerances and f in frame]
    runs = _runs(frame)
    coded = Coded.of(frame)
    causes = _Causes(frame, coded)
    found, n_series, kept = [], 0, []
    for figure in figures:
        rows = coded_rows(coded, figure)
        pts = coded_points(rows)
        series, groups = _sorted_series(pts)
        n_series += len(series)
        value, se = pts["value"].to_numpy(float), pts["se"].to_numpy(float)
        work = [(value[g], se[g]) for g in groups]
        cuts = _proposals(work, jobs)
        margin = gate.tolerances[figure] / FIGURES[figure].scale
        found.append(_judged(figure, margin, (rows, pts), list(zip(series, groups, cuts)), causes))
        found.append(_judged_short(figure, margin, (rows, pts), list(zip(series, groups)), causes))
        # the points and the series' names: not the figure's rows, one per result
        named = replace(rows, **dict.fromkeys(_PER_ROW, np.empty(0)))
        kept.append((figure, named, pts[["series", "run", "value", "se"]]))
    proposals = [f for f in found if len(f)]
    steps = (
        pd.concat(proposals, ignore_index=True)
        if proposals
        else pd.DataFrame([], columns=list(_COLUMNS))
    )
    out = _dated(steps, runs, n_series, gate)
    out.points = _points_of(kept)
    return out


#: the coded rows' arrays of one value per result (:class:`FigureRows`)
_PER_ROW = ("series", "run", "seed", "result", "value", "se", "df", "low_n")


def _points_of(kept: list[tuple[str, FigureRows, pd.DataFrame]]) -> pd.DataFrame:
    """Every figure's points in one frame, its texts categorical: a series' name and label are
    held once, not once per run."""
    if not kept:
        return pd.DataFrame()
    offsets = np.cumsum([0] + [len(rows.names) for _, rows, _ in kept])
    named = np.concatenate([p["series"].to_numpy() + o for (_, _, p), o in zip(kept, offsets)])
    names = np.concatenate([rows.names for _, rows, _ in kept])
    labels = np.concatenate([rows.labels for _, rows, _ in kept])
    pooled = np.concatenate([rows.pooled for _, rows, _ in kept]).astype(int)
    figures = np.array([figure for figure, _, _ in kept], dtype=object)
    sizes = [len(p) for _, _, p in kept]
    return pd.DataFrame(
        {
            "series": categorical(named, names),
            "series_label": categorical(named, labels),
            "kind": categorical(pooled[named], KINDS),
            "run": np.concatenate([p["run"].to_numpy() for _, _, p in kept]),
            "value": np.concatenate([p["value"].to_numpy() for _, _, p in kept]),
            "se": np.concatenate([p["se"].to_numpy() for _, _, p in kept]),
            "figure": categorical(np.repeat(np.arange(len(kept)), sizes), figures),
        }
    )


def _sorted_series(pts: pd.DataFrame) -> tuple[list[int], list[np.ndarray]]:
    """The series of a figure's points in order of first appearance, each its points' rows
    oldest run first."""
    codes = pts["series"].to_numpy()
    series = pd.unique(codes)
    rank = np.empty(int(codes.max(initial=0)) + 1, np.int64)
    rank[series] = np.arange(len(series))
    order = np.lexsort((pts["run"].to_numpy(), rank[codes]))
    ends = np.searchsorted(rank[codes][order], np.arange(len(series)), side="right")
    return series.tolist(), np.split(order, ends[:-1])


def _judged(
    figure: str,
    margin: float,
    table: tuple[FigureRows, pd.DataFrame],
    cut: list[tuple[int, np.ndarray, list[int]]],
    causes: _Causes,
) -> pd.DataFrame:
    """Every proposal of a figure with its change between the segments beside it, judged in
    one batch (:func:`slipbench.history.judging.judge`)."""
    rows, pts = table
    order, starts = _series_slices(rows.series)
    run, low = pts["run"].to_numpy(), pts["low_n"].to_numpy(bool)
    out: dict[str, list] = {c: [] for c in _COLUMNS}
    sides: list[tuple[Side, Side]] = []
    counts: list[int] = []
    for series, group, cuts in cut:
        if not cuts:
            continue
        mine = order[starts[series] : starts[series + 1]]
        seeds = {c: getattr(rows, c)[mine] for c in ("run", "seed", "result", "value", "se", "df")}
        seeds["by_result"] = np.argsort(seeds["result"], kind="stable")
        runs = run[group]
        bounds = [0, *cuts, len(group)]
        # each segment is a side of the proposals on either end of it: its seeds made once
        made = {(i, j): _side(seeds, runs[i], runs[j - 1]) for i, j in zip(bounds, bounds[1:])}
        for a, k, b in zip(bounds, bounds[1:], bounds[2:]):
            pair = (made[a, k], made[k, b])
            sides.append(pair)
            counts.append(len(cuts))
            last, first = int(runs[k - 1]), int(runs[k])
            for column, value in (
                ("series", rows.names[series]),
                ("series_label", rows.labels[series]),
                ("kind", "pooled" if rows.pooled[series] else "cell"),
                ("figure", figure),
                ("run", first),
                ("previous_run", last),
                ("runs_before", k - a),
                ("runs_after", b - k),
                ("first_run", int(runs[a])),
                ("last_run", int(runs[b - 1])),
                ("seeds_before", len(pair[0].value)),
                ("seeds_after", len(pair[1].value)),
                ("low_n", bool(low[group[a:b]].any())),
                ("what_changed", causes.between(series, last, first)),
            ):
                out[column].append(value)
    if not sides:
        return pd.DataFrame()
    out["route"] = [LONG] * len(sides)
    verdicts = judge(sides, figure, margin, (np.array(counts), np.array(out["low_n"])))
    return pd.DataFrame({c: verdicts[c] if c in verdicts else out[c] for c in _COLUMNS})


def _moved(change: Contrast, n: int) -> bool:
    """Whether a short series' best cut is a proposal: its change beyond the tolerance and its
    squared z beyond the price of a cut the segment search asks (``PENALTY * log(points)``)."""
    if not (change.se > 0 and abs(change.estimate) > change.margin):
        return False
    return bool((change.estimate / change.se) ** 2 > PENALTY * math.log(n))


def _judged_short(
    figure: str,
    margin: float,
    table: tuple[FigureRows, pd.DataFrame],
    short: list[tuple[int, np.ndarray]],
    causes: _Causes,
) -> pd.DataFrame:
    """The proposal of every short series of a figure (fewer points than ``2 * MIN_RUNS``, at
    least ``FEWEST``), judged on its runs' own intervals (:mod:`slipbench.history.short`);
    the history's scale measured per kind of series (cells, pooled) over its short series."""
    rows, pts = table
    short = [(s, g) for s, g in short if FEWEST <= len(g) < 2 * MIN_RUNS]
    if not short:
        return pd.DataFrame()
    value, se = pts["value"].to_numpy(float), pts["se"].to_numpy(float)
    df, run, low = pts["df"].to_numpy(float), pts["run"].to_numpy(), pts["low_n"].to_numpy(bool)
    factor = {
        kind: short_scale([(value[g], se[g]) for s, g in short if rows.pooled[s] == kind])
        for kind in (False, True)
    }
    order, starts = _series_slices(rows.series)
    found = []
    for series, group in short:
        n = len(group)
        level = 1 - SERIES_ALPHA / (n - 1)
        k, change = short_change(
            (value[group], se[group], df[group]), factor[bool(rows.pooled[series])], level, margin
        )
        verdict = _verdict(change, figure, bool(low[group].any()), n - 1)
        if verdict["verdict"] not in ("regressed", "improved") and not _moved(change, n):
            continue
        mine = order[starts[series] : starts[series + 1]]
        seeds = {c: getattr(rows, c)[mine] for c in ("run", "seed", "result", "value", "se", "df")}
        seeds["by_result"] = np.argsort(seeds["result"], kind="stable")
        runs = run[group]
        before, after = _side(seeds, runs[0], runs[k - 1]), _side(seeds, runs[k], runs[-1])
        low_n = bool(low[group].any())
        last, first = int(runs[k - 1]), int(runs[k])
        found.append(
            {
                "series": rows.names[series],
                "series_label": rows.labels[series],
                "kind": "pooled" if rows.pooled[series] else "cell",
                "figure": figure,
                "run": first,
                "previous_run": last,
                "runs_before": k,
                "runs_after": n - k,
                "first_run": int(runs[0]),
                "last_run": int(runs[-1]),
                "seeds_before": len(before.value),
                "seeds_after": len(after.value),
                "low_n": low_n,
                **verdict,
                "what_changed": causes.between(series, last, first),
                "runs_needed": _runs_needed(
                    change, n - 1, min(len(before.value), len(after.value))
                ),
                "route": SHORT,
            }
        )
    return pd.DataFrame(found, columns=list(_COLUMNS))


def _side(rows: dict[str, np.ndarray], first: int, last: int) -> Side:
    """A segment's seeds (its runs ``first`` to ``last``): the results of its runs, each once
    (a result a later run kept, with the same code and seed, is one), and the results of one
    seed as one (they share its split and test trials): their mean, mean standard error and
    fewest degrees of freedom. ``rows`` holds ``by_result``, the series' rows stably sorted by
    result: the segment's rows in that order, the first of each result, are what
    ``np.unique(..., return_index=True)`` would pick, without a sort per segment."""
    by_result = rows["by_result"]
    run = rows["run"][by_result]
    inside = by_result[(run >= first) & (run <= last)]
    result = rows["result"][inside]
    pick = inside[np.concatenate([[True], result[1:] != result[:-1]])] if len(inside) else inside
    seeds, at = np.unique(rows["seed"][pick], return_inverse=True)
    count = np.bincount(at, minlength=len(seeds))
    value = np.bincount(at, rows["value"][pick].astype(float), len(seeds)) / count
    se = np.bincount(at, rows["se"][pick].astype(float), len(seeds)) / count
    df = np.full(len(seeds), np.inf)
    np.minimum.at(df, at, rows["df"][pick].astype(float))
    return Side(value, se, df)


def _dated(steps: pd.DataFrame, runs: pd.DataFrame, n_series: int, gate: Gate) -> Steps:
    """The proposals with their runs' commits and dates."""
    steps = steps.copy()
    by_run = runs.set_index("run")
    for side, column in (("", "run"), ("previous_", "previous_run")):
        for what in ("commit", "date"):
            steps[f"{side}{what}"] = steps[column].map(by_run[what])
    # whether a run of either side holds rows no digest vouches for: marked, not judged apart
    held = np.concatenate([[0], np.cumsum(by_run["unproven"].reindex(range(len(runs))).fillna(0))])
    first, last = steps["first_run"].to_numpy(int), steps["last_run"].to_numpy(int)
    steps["unproven"] = held[last + 1] > held[first]
    return Steps(steps, runs, n_series, gate=gate)


def default_jobs() -> int:
    """The processes that cut series by default: this machine's cores."""
    return os.cpu_count() or 1
