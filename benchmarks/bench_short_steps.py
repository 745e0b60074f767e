"""Short histories: does `history steps` name a step of 5 to 8 commits, and stay quiet without one?

A series shorter than ``2 * MIN_RUNS`` runs is judged on its runs' own intervals
(:mod:`slipbench.history.short`). Each simulated history has ``--commits`` commits; commit i
runs the bench shipped when the pool was drawn (holweg and bandpass, window-size and
cross-instance: 114 cells) under a seed drawn for it, with replacement, from the pool of real
runs of that bench at 40 seeds (``benchmarks/results/history_pool.parquet``, as
``history_study.py`` reads it): each run's test noise, its seed's split and training
included, and its own recorded intervals. Each commit has its own code identity.

In a history with a step, holweg's accuracy in every cell drops by ``--steps`` points (its
bounds with it) from commit k on, k drawn uniformly from the second commit to the last. A step
is *named* where a confirmed regression of a holweg accuracy series lies at k exactly; every
other confirmed step is a false alarm. Reported per history size:

- false alarms per series (confirmed steps over series judged) and per history (histories
  with at least one), in histories without a step;
- power: the histories whose step is named (at the pooled series or any cell), and the share
  of holweg's accuracy series (cells and pooled) named at k.

Run::

    nice -n 10 python benchmarks/bench_short_steps.py \\
        --pool benchmarks/results/history_pool.parquet --out benchmarks/results/short_steps.md
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np
import pandas as pd

from slipbench.gate.gate import Gate
from slipbench.history.series import series_rows
from slipbench.history.short import scale, short_change
from slipbench.history.steps import JUDGED, MIN_RUNS, SERIES_ALPHA, find_steps
from slipbench.seeding import rng_for
from slipbench.store.results import read_results

STEPPED = "holweg"
FIGURE = "accuracy"
MARGIN = 0.01  # the gate's default tolerance, 1 point, as a fraction


def series_by_seed(pool: pd.DataFrame, figure: str) -> list[tuple]:
    """Every series of ``figure`` as find_steps makes it from the pool, by seed: per kind
    (cells; each protocol and detector's mean over its cells, its se the cells' mean, its df
    the fewest) values, standard errors and df (series x seed) and whether it is holweg's."""
    ok = pool[pool["status"] == "ok"]
    cells = ok.pivot_table(
        index=["protocol", "detector", "cell"],
        columns="seed",
        values=[figure, f"{figure}_se", "df"],
        aggfunc="first",
    )
    v, s, d = (cells[c].to_numpy(float) for c in (figure, f"{figure}_se", "df"))
    index = cells.index.to_frame(index=False)
    ours = (index["detector"] == STEPPED).to_numpy()
    pool_of = index.groupby(["protocol", "detector"]).ngroup().to_numpy()
    groups = np.unique(pool_of)
    pooled = (
        np.array([v[pool_of == g].mean(0) for g in groups]),
        np.array([s[pool_of == g].mean(0) for g in groups]),
        np.array([d[pool_of == g].min(0) for g in groups]),
        np.array([ours[pool_of == g][0] for g in groups]),
    )
    return [(v, s, d, ours), pooled]


def simulated(kinds: dict, commits: int, points: float, h: int) -> dict:
    """One history judged series by series as find_steps judges a short series
    (:func:`slipbench.history.short.short_change`, the scale per figure and kind)."""
    rng = rng_for(h, "short-steps-points", commits, points)
    pick = rng.integers(0, next(iter(kinds.values()))[0][0].shape[1], commits)
    k = int(rng.integers(1, commits)) if points else None
    out = {"commits": commits, "step": points, "k": k, "false": 0, "series": 0}
    out |= {"named": False, "pooled named": False, "series named": 0, "targets": 0}
    for figure, per_kind in kinds.items():
        for kind, (v, s, d, ours) in zip(("cell", "pooled"), per_kind):
            value, se, df = v[:, pick].copy(), s[:, pick], d[:, pick]
            stepped = ours if figure == FIGURE and k is not None else np.zeros(len(ours), bool)
            value[np.ix_(stepped, np.arange(k or 0, commits))] -= points / 100
            rows = np.flatnonzero(np.isfinite(value).all(1) & np.isfinite(se).all(1))
            factor = scale([(value[i], se[i]) for i in rows])
            level = 1 - SERIES_ALPHA / (commits - 1)
            out["targets"] += int(stepped[rows].sum())
            for i in rows:
                cut, change = short_change((value[i], se[i], df[i]), factor, level, MARGIN)
                out["series"] += 1
                hit = stepped[i] and cut == k and change.hi < -MARGIN
                if hit:
                    out["named"] = True
                    out["pooled named"] |= kind == "pooled"
                    out["series named"] += 1
                elif change.lo > MARGIN or change.hi < -MARGIN:
                    out["false"] += 1
    return out


def history(kept: dict, seeds: np.ndarray, k: int | None, points: float) -> pd.DataFrame:
    """A history's rows: commit i is the pool's run of ``seeds[i]`` (its history rows made
    once, ``kept``), re-keyed as its own result under its own code; from ``k`` on, holweg's
    accuracy ``points`` lower."""
    parts = []
    for i, seed in enumerate(seeds):
        rows = kept[seed].copy()
        rows["key"] = rows["key"] + f"-{i}"
        rows["code_identity"] = f"code-{i}"
        if k is not None and i >= k:
            rows.loc[rows["detector_id"] == STEPPED, FIGURE] -= points / 100
        rows["commit"], rows["date"] = f"c{i:03d}", f"2026-01-01T00:{i:02d}:00Z"
        rows["machine"], rows["bench_digest"], rows["run"] = "study", "", i
        parts.append(rows)
    return pd.concat(parts, ignore_index=True)


def one(kept: dict, commits: int, points: float, h: int, gate: Gate) -> dict:
    rng = rng_for(h, "short-steps", commits, points)
    seeds = rng.choice(np.array(sorted(kept)), commits, replace=True)
    k = int(rng.integers(1, commits)) if points else None
    found = find_steps(history(kept, seeds, k, points), gate, jobs=1)
    c = found.confirmed
    ours = c["series_label"].str.contains(f" · {STEPPED} · ") & (c["figure"] == FIGURE)
    hit = ours & (c["verdict"] == "regressed") & (c["run"] == (k if k is not None else -1))
    targets = found.points[
        found.points["series_label"].str.contains(f" · {STEPPED} · ")
        & (found.points["figure"] == FIGURE)
    ]["series"].nunique()
    return {
        "commits": commits,
        "step": points,
        "k": k,
        "named": bool(hit.any()),
        "pooled named": bool((hit & (c["kind"] == "pooled")).any()),
        "series named": int(hit.sum()),
        "targets": int(targets),
        "false": int((~hit).sum()),
        "series": found.series,
    }


def summary(table: pd.DataFrame) -> pd.DataFrame:
    rows = []
    for (commits, step), g in table.groupby(["commits", "step"]):
        row = {"commits": commits, "step (points)": step, "histories": len(g)}
        row["false alarms per 100 series"] = 100 * g["false"].sum() / g["series"].sum()
        row["histories with a false alarm"] = f"{int((g['false'] > 0).sum())} / {len(g)}"
        if step:
            row["step named (histories)"] = f"{int(g['named'].sum())} / {len(g)}"
            row["named in the pooled series"] = f"{int(g['pooled named'].sum())} / {len(g)}"
            row["holweg accuracy series named"] = (
                f"{100 * g['series named'].sum() / g['targets'].sum():.0f} %"
            )
        rows.append(row)
    return pd.DataFrame(rows).fillna("")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pool", type=Path, required=True)
    parser.add_argument("--histories", type=int, default=200)
    parser.add_argument("--end-to-end", type=int, default=6, help="histories through find_steps")
    parser.add_argument("--commits", type=int, nargs="+", default=[5, 6, 8])
    parser.add_argument("--steps", type=float, nargs="+", default=[3.0, 5.0, 10.0])
    parser.add_argument("--out", type=Path)
    a = parser.parse_args()
    pool = read_results(a.pool)
    gate = Gate.of(JUDGED)
    start = time.perf_counter()
    kinds = {f: series_by_seed(pool, f) for f in JUDGED}
    table = pd.DataFrame(
        [
            simulated(kinds, commits, points, h)
            for commits in a.commits
            for points in (0.0, *a.steps)
            for h in range(a.histories)
        ]
    )
    took = time.perf_counter() - start
    kept = {s: series_rows(part) for s, part in pool.groupby("seed")}
    start = time.perf_counter()
    ends = pd.DataFrame(
        [
            one(kept, commits, points, h, gate)
            for commits in a.commits[:1]
            for points in (0.0, a.steps[-1])
            for h in range(a.end_to_end)
        ]
    )
    took_ends = time.perf_counter() - start
    text = (
        f"History steps in short histories ({', '.join(map(str, a.commits))} commits). "
        f"Pool: {a.pool.name}, {pool['seed'].nunique()} seeds of the bench then shipped "
        f"({len(pool)} rows: {', '.join(sorted(pool['detector'].unique()))}); gate tolerances "
        f"{dict(gate.tolerances)} (points); seeds drawn per commit with replacement; "
        f"{STEPPED}'s {FIGURE} stepped in every cell at a commit drawn from the 2nd to the "
        f"last; series judged at SERIES_ALPHA = {SERIES_ALPHA} (Bonferroni over a series' "
        f"cuts).\n\n"
        "Series by series, as `find_steps` judges a short series (each series' points from "
        "the pool, the scale per figure and kind over the history's series)"
        + (
            f"; a history of {2 * MIN_RUNS} commits or more is judged here by the short route "
            "too, for comparison, where `find_steps` gives its series to the segment search"
            if max(a.commits) >= 2 * MIN_RUNS
            else ""
        )
        + ":\n\n"
        f"{summary(table).to_markdown(index=False, floatfmt='.2f')}\n\n"
        f"{len(table)} histories in {took:.0f} s.\n\n"
        "End to end, the histories' rows through `find_steps` (fewer: it is slower):\n\n"
        f"{summary(ends).to_markdown(index=False, floatfmt='.2f')}\n\n"
        f"{len(ends)} histories in {took_ends:.0f} s on {os.cpu_count()} cores "
        f"(load average {os.getloadavg()[0]:.1f} at the end).\n"
    )
    print(text)
    if a.out:
        a.out.write_text(text)


if __name__ == "__main__":
    main()
