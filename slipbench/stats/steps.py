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
counts once), and :func:`step_change` (the one place this module calls the comparison
machinery) gives the change with its standard error and degrees of freedom. It is tested
against the figure's tolerance in the gate (:mod:`slipbench.stats.gate`); Bonferroni holds
the family of every proposal in the history at ``ALPHA`` (5 %), and each interval is shown at
that level, so that an interval beyond the tolerance and a confirmed step are one statement.
A step is *regressed* or *improved* where its change is beyond the tolerance at that level,
else *not confirmed*; proposals in low-n cells (fewer than ``LOW_N`` test trials of a class)
are *inconclusive*.

The gate's windowed figures (accuracy, TN rate, TP rate) are judged, per cell and pooled over
a protocol's cells; streaming series are kept and plotted, and judged once compare judges
streams of several seeds a side.
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import ruptures as rpt
from ruptures.base import BaseCost
from scipy.stats import t as student_t

from slipbench.stats.compare import ALPHA, unpaired_cell
from slipbench.stats.gate import SCALE, WINDOWED, WORSE, Gate, two_sided_p
from slipbench.stats.metrics import FIGURES
from slipbench.stats.series import figure_rows, points

#: the price of a cut, times the series' noise scale and log(points)
PENALTY = 6.0
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
    *(c for _, c in CAUSES),
    *(f"{f}{end}" for f in WINDOWED for end in ("", "_se")),
]
#: the chance that a series without a step gets a confirmed one (Bonferroni over its proposals)
SERIES_ALPHA = 0.01
#: points per worker process below which the series are cut in this process (starting the
#: workers costs more than cutting; benchmarks/bench_history.py)
POINTS_PER_WORKER = 200_000
#: a proposal's verdicts
VERDICTS = ("regressed", "improved", "not confirmed", "inconclusive")


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


def _sides(before: list[dict], after: list[dict], figure: str) -> tuple[dict, dict]:
    """Both segments as one row each: the mean of its seeds, and a standard error from their
    spread pooled over both segments (a step moves the figure, not the bench's seed noise) on
    ``seeds - 2`` degrees of freedom. Where each segment holds one seed, nothing measures that
    noise: each row keeps its own interval (test-set noise alone)."""
    unknown = {f"{name}_se": np.nan for name in FIGURES}  # the figures not judged here
    if len(before) + len(after) <= 2:
        return unknown | before[0], unknown | after[0]
    values = [np.array([r[figure] for r in side], float) for side in (before, after)]
    df = float(len(values[0]) + len(values[1]) - 2)
    variance = sum(float(((v - v.mean()) ** 2).sum()) for v in values) / df
    return tuple(  # type: ignore[return-value]
        unknown | {figure: float(v.mean()), f"{figure}_se": np.sqrt(variance / len(v)), "df": df}
        for v in values
    )


def step_change(before: list[dict], after: list[dict], figure: str, level: float) -> dict:
    """The change of ``figure`` from the seeds ``before`` to those ``after`` (each a row with
    the figure, its ``_se`` and ``df``), by the gate's comparison of two rows
    (:func:`slipbench.stats.compare.unpaired_cell`), each side the mean of its seeds with the
    standard error of their pooled spread (:func:`_sides`). Returns ``d``, ``se``, ``df`` and
    the interval ``lo``, ``hi`` at ``level``, in the figure's stored units.

    The one place steps call the comparison machinery: the contrast module replaces it.
    """
    b, a = _sides(before, after, figure)
    found = unpaired_cell([b], [a], level)
    return {
        "d": found[f"d_{figure}"],
        "se": found[f"d_{figure}_se"],
        "df": found["df"],
        "lo": found[f"d_{figure}_lo"],
        "hi": found[f"d_{figure}_hi"],
    }


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
    return (
        frame.groupby("run", sort=True)[["commit", "date", "machine", "bench_digest"]]
        .first()
        .reset_index()
    )


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
    figures = [f for f in WINDOWED if f in gate.tolerances and f in frame]
    runs = _runs(frame)
    causes = (_by_series(frame, ["run", *(c for _, c in CAUSES)]), _run_causes(frame))
    found, n_series, kept = [], 0, []
    for figure in figures:
        rows = figure_rows(frame, figure)
        seeds = _by_series(rows, ["run", "seed", "result", "value", "se", "df"])
        pts = points(rows)
        groups = [g.sort_values("run") for _, g in pts.groupby("series", sort=False)]
        n_series += len(groups)
        for g, cuts in zip(groups, _proposals(groups, jobs)):
            series = g["series"].iloc[0]
            mine = causes[0].get(series, causes[1]) if g["kind"].iloc[0] == "cell" else causes[1]
            found += _judge_series(g, cuts, figure, seeds[series], mine)
        kept.append(
            pts[["series", "series_label", "kind", "run", "value", "se"]].assign(figure=figure)
        )
    steps = pd.DataFrame(found, columns=list(_COLUMNS))
    out = _verdicts(steps, runs, n_series, gate)
    out.points = pd.concat(kept, ignore_index=True) if kept else pd.DataFrame()
    return out


_COLUMNS = {
    "series": str,
    "series_label": str,
    "kind": str,
    "figure": str,
    "run": int,
    "previous_run": int,
    "runs_before": int,
    "runs_after": int,
    "seeds_before": int,
    "seeds_after": int,
    "low_n": bool,
    "d": float,
    "se": float,
    "df": float,
    "what_changed": str,
}


def _judge_series(
    pts: pd.DataFrame, cuts: list[int], figure: str, rows: dict[str, np.ndarray], causes: dict
) -> list[dict]:
    """Each proposed cut of one series with its change between the segments beside it."""
    bounds = [0, *cuts, len(pts)]
    runs = pts["run"].to_numpy()
    out = []
    for a, k, b in zip(bounds, bounds[1:], bounds[2:]):
        sides = [_seeds(runs[i:j], figure, rows) for i, j in ((a, k), (k, b))]
        change = step_change(sides[0], sides[1], figure, 1 - ALPHA)
        last, first = int(runs[k - 1]), int(runs[k])
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
                "seeds_before": len(sides[0]),
                "seeds_after": len(sides[1]),
                "low_n": bool(pts["low_n"].iloc[a:b].any()),
                "d": change["d"],
                "se": change["se"],
                "df": change["df"],
                "what_changed": _what_changed(causes, last, first),
            }
        )
    return out


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


def _verdicts(steps: pd.DataFrame, runs: pd.DataFrame, n_series: int, gate: Gate) -> Steps:
    """Bonferroni over each series' proposals at ``SERIES_ALPHA``, the level of the interval
    shown beside each; one seed on each side or low n: inconclusive."""
    steps = steps.copy()
    scale = steps["figure"].map(SCALE).to_numpy(float)
    sign = steps["figure"].map(WORSE).to_numpy(float)
    tol = steps["figure"].map(gate.tolerances).to_numpy(float)
    d, se = scale * steps["d"].to_numpy(float), scale * steps["se"].to_numpy(float)
    df = steps["df"].to_numpy(float)
    p_worse, p_better = two_sided_p(sign * d, se, df, tol)
    alone = (steps["seeds_before"] + steps["seeds_after"] <= 2).to_numpy(bool)
    testable = ~steps["low_n"].to_numpy(bool) & ~alone
    m = steps.groupby(["series", "figure"])["run"].transform("size").to_numpy(float)
    # Bonferroni, not Holm: every verdict then rests on the interval printed beside it
    steps["p_adjusted"] = np.where(
        testable, np.minimum(1.0, m * np.minimum(p_worse, p_better)), 1.0
    )
    steps["level"] = 1 - SERIES_ALPHA / np.maximum(m, 1)
    q = student_t.ppf(1 - (1 - steps["level"].to_numpy(float)) / 2, df)
    steps["change"], steps["change_lo"], steps["change_hi"] = d, d - q * se, d + q * se
    steps["tolerance"] = tol
    steps["verdict"] = [
        "inconclusive"
        if not ok
        else ("regressed" if w <= b else "improved")
        if ph <= SERIES_ALPHA
        else "not confirmed"
        for ok, ph, w, b in zip(testable, steps["p_adjusted"], p_worse, p_better)
    ]
    steps["why"] = np.where(alone, "one seed on each side", np.where(steps["low_n"], "low n", ""))
    by_run = runs.set_index("run")
    for side, column in (("", "run"), ("previous_", "previous_run")):
        for what in ("commit", "date"):
            steps[f"{side}{what}"] = steps[column].map(by_run[what])
    return Steps(steps, runs, n_series, gate=gate)


def default_jobs() -> int:
    """The processes that cut series by default: this machine's cores."""
    return os.cpu_count() or 1
