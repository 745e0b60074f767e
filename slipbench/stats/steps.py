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
against the figure's tolerance in the gate (:mod:`slipbench.stats.gate`) and Holm holds the
family of every proposal in the history at ``ALPHA`` (5 %), as compare holds its cells. A step
is *regressed* or *improved* where its change is beyond the tolerance at that level, else *not
confirmed*; proposals in low-n cells (fewer than ``LOW_N`` test trials of a class) are
*inconclusive*. Intervals are shown at the family's Bonferroni level.

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

from slipbench.stats.compare import ALPHA, family_level, unpaired_cell
from slipbench.stats.gate import SCALE, WINDOWED, WORSE, Gate, holm, two_sided_p
from slipbench.stats.series import points, pooled_rows

#: the price of a cut, times the series' noise scale and log(points)
PENALTY = 3.0
#: the fewest runs a segment holds
MIN_RUNS = 2
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


def step_change(before: list[dict], after: list[dict], figure: str, level: float) -> dict:
    """The change of ``figure`` from the results ``before`` to those ``after`` (each a row
    with the figure, its ``_se`` and ``df``; each side's rows its seeds), as the gate's
    comparison gives it from rows (:func:`slipbench.stats.compare.unpaired_cell`): ``d``,
    ``se``, ``df`` and the interval ``lo``, ``hi`` at ``level``, in the figure's stored units.
    """
    found = unpaired_cell(before, after, level)
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
    level: float = 1 - ALPHA

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
    found, n_series, kept = [], 0, []
    for figure in figures:
        cells = points(frame, figure)
        pooled = pooled_rows(cells, figure)
        for kind, pts in (("cell", cells), ("pooled", pooled)):
            groups = [g.sort_values("run") for _, g in pts.groupby("series", sort=False)]
            n_series += len(groups)
            for g, cuts in zip(groups, _proposals(groups, jobs)):
                found += _judge_series(g, cuts, figure, kind, frame)
            kept.append(
                pts[["series", "series_label", "run", "value", "se"]].assign(
                    figure=figure, kind=kind
                )
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
    pts: pd.DataFrame, cuts: list[int], figure: str, kind: str, frame: pd.DataFrame
) -> list[dict]:
    """Each proposed cut of one series with its change between the segments beside it."""
    bounds = [0, *cuts, len(pts)]
    out = []
    for a, k, b in zip(bounds, bounds[1:], bounds[2:]):
        before, after = pts.iloc[a:k], pts.iloc[k:b]
        sides = [_seeds(part, figure, kind, frame) for part in (before, after)]
        change = step_change(sides[0], sides[1], figure, 1 - ALPHA)
        out.append(
            {
                "series": pts["series"].iloc[0],
                "series_label": pts["series_label"].iloc[0],
                "kind": kind,
                "figure": figure,
                "run": int(after["run"].iloc[0]),
                "previous_run": int(before["run"].iloc[-1]),
                "runs_before": len(before),
                "runs_after": len(after),
                "seeds_before": len(sides[0]),
                "seeds_after": len(sides[1]),
                "low_n": bool(before["low_n"].any() or after["low_n"].any()),
                "d": change["d"],
                "se": change["se"],
                "df": change["df"],
                "what_changed": _what_changed(
                    frame, pts, int(before["run"].iloc[-1]), int(after["run"].iloc[0]), kind
                ),
            }
        )
    return out


def _seeds(part: pd.DataFrame, figure: str, kind: str, frame: pd.DataFrame) -> list[dict]:
    """A segment's results as seeds: the rows of its runs (a pooled series: its points), each
    result once."""
    if kind == "pooled":
        kept = part.drop_duplicates("results")
        return [
            {figure: v, f"{figure}_se": s, "df": d}
            for v, s, d in zip(kept["value"], kept["se"], kept["df"])
        ]
    rows = frame[
        (frame["series"] == part["series"].iloc[0])
        & frame["run"].isin(part["run"])
        & (frame["status"] == "ok")
        & frame[figure].notna()
    ].drop_duplicates("key")
    return [
        {figure: float(v), f"{figure}_se": float(s), "df": float(d)}
        for v, s, d in zip(rows[figure], rows[f"{figure}_se"], rows["df"].fillna(np.inf))
    ]


def _what_changed(
    frame: pd.DataFrame, pts: pd.DataFrame, before: int, after: int, kind: str
) -> str:
    """What the run of a step changed against the run before, in the rows it holds."""
    # a pooled series: the whole runs (its cells' rows)
    rows = frame[frame["series"] == pts["series"].iloc[0]] if kind == "cell" else frame
    a, b = (rows[rows["run"] == r] for r in (before, after))
    found = [
        name
        for name, column in (
            ("code", "code_identity"),
            ("parameters", "detector_params"),
            ("dataset", "dataset_fingerprint"),
            ("bench file", "bench_digest"),
        )
        if set(a[column].dropna().astype(str)) != set(b[column].dropna().astype(str))
    ]
    return ", ".join(found) or "seeds only"


def _verdicts(steps: pd.DataFrame, runs: pd.DataFrame, n_series: int, gate: Gate) -> Steps:
    """Holm over every proposal at ``ALPHA``; intervals at the family's Bonferroni level."""
    level = family_level(len(steps), ALPHA)
    steps = steps.copy()
    scale = steps["figure"].map(SCALE).to_numpy(float)
    sign = steps["figure"].map(WORSE).to_numpy(float)
    tol = steps["figure"].map(gate.tolerances).to_numpy(float)
    d, se = scale * steps["d"].to_numpy(float), scale * steps["se"].to_numpy(float)
    df = steps["df"].to_numpy(float)
    p_worse, p_better = two_sided_p(sign * d, se, df, tol)
    testable = ~steps["low_n"].to_numpy(bool)
    p = np.where(testable, np.minimum(p_worse, p_better), 1.0)
    steps["p_holm"] = holm(p) if len(p) else p
    q = student_t.ppf(1 - (1 - level) / 2, df) if len(df) else df
    steps["change"], steps["change_lo"], steps["change_hi"] = d, d - q * se, d + q * se
    steps["tolerance"] = tol
    steps["verdict"] = [
        "inconclusive"
        if not ok
        else ("regressed" if w <= b else "improved")
        if ph <= ALPHA
        else "not confirmed"
        for ok, ph, w, b in zip(testable, steps["p_holm"], p_worse, p_better)
    ]
    by_run = runs.set_index("run")
    for side, column in (("", "run"), ("previous_", "previous_run")):
        for what in ("commit", "date"):
            steps[f"{side}{what}"] = steps[column].map(by_run[what])
    return Steps(steps, runs, n_series, gate=gate, level=level)


def default_jobs() -> int:
    """The processes that cut series by default: this machine's cores."""
    return os.cpu_count() or 1
