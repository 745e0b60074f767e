"""Steps in a history's series: proposed by ruptures, confirmed by the gate's test.

*Proposed.* Each series' points over runs (:func:`slipbench.stats.series.points`, one per run,
oldest first) are cut by binary segmentation (``ruptures.Binseg``) under a cost that weighs
every point by its interval: :class:`WeightedL2`, the precision-weighted squared error about
each segment's weighted mean (asv weighs its steps the same way). The intervals hold a run's
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
import ruptures as rpt
from ruptures.base import BaseCost

from slipbench.gate.gate import Gate, needed, resolution, scaled_resolution
from slipbench.history.series import figure_rows, points
from slipbench.stats.contrast import (
    ONE_SEED,
    SHOWN,
    TEST_NOISE,
    Contrast,
    family_level,
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
    "protocol",
    "protocol_params",
    "split",
    "labels",
    "detector",
    "cell",
    "proven",
    *(c for _, c in CAUSES),
    *(f"{f}{end}" for f in JUDGED for end in ("", "_se")),
]
#: where a step's seed noise was measured where no other source is given
SEGMENT_SEEDS = "the seeds of the segments beside the step"
#: the chance that a series without a step gets a confirmed one (Bonferroni over its proposals)
SERIES_ALPHA = 0.01
#: points per worker process below which the series are cut in this process (starting the
#: workers costs more than cutting; benchmarks/bench_history.py)
POINTS_PER_WORKER = 200_000


class WeightedL2(BaseCost):
    """The cost of a segment: sum of ``w * (y - mean_w)**2``, ``w`` each point's precision
    (1 / its standard error squared), in O(1) from prefix sums. The signal is (n, 2): the
    values and their weights."""

    model = "weighted-l2"
    min_size = MIN_RUNS

    def fit(self, signal: np.ndarray) -> WeightedL2:
        y, w = signal[:, 0], signal[:, 1]
        # lists: one element read is 3x faster than from an array, and Binseg reads 4n of them
        self._w = np.concatenate([[0.0], np.cumsum(w)]).tolist()
        self._s = np.concatenate([[0.0], np.cumsum(w * y)]).tolist()
        self._q = np.concatenate([[0.0], np.cumsum(w * y * y)]).tolist()
        self.signal = signal
        return self

    def error(self, start: int, end: int) -> float:
        s = self._s[end] - self._s[start]
        return self._q[end] - self._q[start] - s * s / (self._w[end] - self._w[start])


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
    """The indices where a new segment starts (none: no step proposed), from Binseg under
    :class:`WeightedL2` with the penalty of the module's docstring."""
    n = len(value)
    if n < 2 * MIN_RUNS:
        return []
    floor = np.nanmedian(se[se > 0]) if np.any(se > 0) else 1.0
    se = np.where(np.isfinite(se) & (se > 0), se, floor)  # a point without spread: the median's
    pen = PENALTY * noise_scale(value, se) * math.log(n)
    signal = np.column_stack([value, 1.0 / se**2])
    algo = rpt.Binseg(custom_cost=WeightedL2(), min_size=MIN_RUNS, jump=1).fit(signal)
    return [int(b) for b in algo.predict(pen=pen)[:-1]]


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


def _proposals(series: list[pd.DataFrame], jobs: int) -> list[list[int]]:
    """Binseg over every series, in ``jobs`` processes where the points are many enough."""
    work = [(p["value"].to_numpy(float), p["se"].to_numpy(float)) for p in series]
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
    proven = frame["proven"] if "proven" in frame else pd.Series(True, index=frame.index)
    runs["unproven"] = (~proven.fillna(False).astype(bool)).groupby(frame["run"]).sum()
    return runs.reset_index()


def _by_series(frame: pd.DataFrame, columns: list[str]) -> dict[str, dict[str, np.ndarray]]:
    """Each series' ``columns`` as arrays: a proposal reads a few rows, and selecting them
    from a frame costs a thousand times the work."""
    arrays = {c: frame[c].to_numpy() for c in columns}
    order = np.argsort(frame["series"].to_numpy(), kind="stable")
    names, starts = np.unique(frame["series"].to_numpy()[order], return_index=True)
    ends = [*starts[1:], len(order)]
    return {
        str(n): {c: a[order[i:j]] for c, a in arrays.items()}
        for n, i, j in zip(names, starts, ends)
    }


def _run_causes(frame: pd.DataFrame) -> dict[int, dict[str, frozenset]]:
    """Per run, the values each cause column holds (a pooled series' runs are its cells')."""
    out: dict[int, dict[str, frozenset]] = {}
    for _, column in CAUSES:
        pairs = pd.DataFrame({"run": frame["run"], "v": frame[column]}).drop_duplicates()
        for run, values in pairs.groupby("run")["v"]:
            out.setdefault(int(run), {})[column] = frozenset(map(str, values))
    return out


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
    causes = (_by_series(frame, ["run", *(c for _, c in CAUSES)]), _run_causes(frame))
    found, n_series, kept = [], 0, []
    for figure in figures:
        margin = gate.tolerances[figure] / FIGURES[figure].scale
        rows = figure_rows(frame, figure)
        seeds = _by_series(rows, ["run", "seed", "result", "value", "se", "df"])
        pts = points(rows)
        groups = [g.sort_values("run") for _, g in pts.groupby("series", sort=False)]
        n_series += len(groups)
        for g, cuts in zip(groups, _proposals(groups, jobs)):
            series = g["series"].iloc[0]
            mine = causes[0].get(series, causes[1]) if g["kind"].iloc[0] == "cell" else causes[1]
            found += _judge_series(g, cuts, (figure, margin), seeds[series], mine)
        kept.append(
            pts[["series", "series_label", "kind", "run", "value", "se"]].assign(figure=figure)
        )
    steps = pd.DataFrame(found, columns=list(_COLUMNS))
    out = _dated(steps, runs, n_series, gate)
    out.points = pd.concat(kept, ignore_index=True) if kept else pd.DataFrame()
    return out


def _judge_series(
    pts: pd.DataFrame,
    cuts: list[int],
    judged: tuple[str, float],
    rows: dict[str, np.ndarray],
    causes: dict,
) -> list[dict]:
    """Each proposed cut of one series with its change between the segments beside it, at the
    level that holds the series' proposals together; ``judged``: the figure and its margin."""
    figure, margin = judged
    bounds = [0, *cuts, len(pts)]
    runs = pts["run"].to_numpy()
    level = family_level(len(cuts), SERIES_ALPHA)
    out = []
    for a, k, b in zip(bounds, bounds[1:], bounds[2:]):
        sides = [_seeds(runs[i:j], figure, rows) for i, j in ((a, k), (k, b))]
        change = step_change((sides[0], sides[1]), figure, level, margin)
        last, first = int(runs[k - 1]), int(runs[k])
        low_n = bool(pts["low_n"].iloc[a:b].any())
        out.append(
            {
                "series": pts["series"].iloc[0],
                "series_label": pts["series_label"].iloc[0],
                "kind": pts["kind"].iloc[0],
                "figure": figure,
                "run": first,
                "previous_run": last,
                "runs_before": k - a,
                "runs_after": b - k,
                "first_run": int(runs[a]),
                "last_run": int(runs[b - 1]),
                "seeds_before": len(sides[0]),
                "seeds_after": len(sides[1]),
                "low_n": low_n,
                **_verdict(change, figure, low_n, len(cuts)),
                "runs_needed": _runs_needed(change, len(cuts), min(map(len, sides))),
                "what_changed": _what_changed(causes, last, first),
            }
        )
    return out


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
    measured with this spread, is confirmed with the gate's power (:func:`slipbench.stats.gate.needed`,
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
}


def _seeds(runs: np.ndarray, figure: str, rows: dict[str, np.ndarray]) -> list[dict]:
    """A segment's seeds: the results of its runs, each once (a result a later run kept, with
    the same code and seed, is one), and the results of one seed as one (they share its split
    and test trials): their mean, mean standard error and fewest degrees of freedom."""
    mask = np.isin(rows["run"], runs)
    _, first = np.unique(rows["result"][mask], return_index=True)
    pick = np.flatnonzero(mask)[first]
    seeds, at = np.unique(rows["seed"][pick], return_inverse=True)
    count = np.bincount(at, minlength=len(seeds))
    value = np.bincount(at, rows["value"][pick].astype(float), len(seeds)) / count
    se = np.bincount(at, rows["se"][pick].astype(float), len(seeds)) / count
    df = np.full(len(seeds), np.inf)
    np.minimum.at(df, at, rows["df"][pick].astype(float))
    return [
        {figure: float(v), f"{figure}_se": float(s), "df": float(d)}
        for v, s, d in zip(value, se, df)
    ]


def _what_changed(causes: dict, before: int, after: int) -> str:
    """What the run ``after`` changed against the run ``before``: in a series' rows (arrays),
    or in the runs' sets of each cause (:func:`_run_causes`)."""
    if "run" in causes:
        a, b = (causes["run"] == r for r in (before, after))
        differ = [set(map(str, causes[c][a])) != set(map(str, causes[c][b])) for _, c in CAUSES]
    else:
        differ = [causes[before][c] != causes[after][c] for _, c in CAUSES]
    return ", ".join(name for (name, _), d in zip(CAUSES, differ) if d) or "seeds only"


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
