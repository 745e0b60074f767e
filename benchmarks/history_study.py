"""Does `history steps` name a 2-point step at its commit, and stay quiet where there is none?

Each simulated history has ``--commits`` commits. Commit i runs the bench shipped when the pool
was drawn (holweg and bandpass, window-size at 50 and 100 and cross-instance, grouped, scale
0.05) under
a seed drawn for it from a pool of real runs of that bench at many seeds: the bench's own
noise, the seed's split and its test trials included. Each commit has its own code identity.
In a history with a step, every figure the gate reads (accuracy, TN rate, TP rate) of every
holweg cell drops by 2 points from commit k on (k drawn in the middle half); the steps are
then found and confirmed against the gate's default tolerances (1 point each: what `history
steps` judges without --bench; a 2-point step is beyond them).

A step is *named* when a confirmed regression of a holweg series lies at k +- 1; every other
confirmed step counts as false. Histories without a step count their confirmed steps per
series judged.

The pool: `slipbench run` of bench.toml with ``repeats = 40`` (seeds 0-39), its rows kept
in ``benchmarks/results/history_pool.parquet`` (the columns a history keeps)::

    python benchmarks/history_study.py --pool benchmarks/results/history_pool.parquet \\
        --out benchmarks/results/history_study.md
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
from slipbench.history.steps import JUDGED, find_steps
from slipbench.seeding import rng_for
from slipbench.store.results import read_results

STEP = 0.02  # 2 points, as a fraction
STEPPED = "holweg"
BOUNDS = ("", "_lo", "_hi")


def history(pool: pd.DataFrame, seeds: np.ndarray, k: int | None) -> pd.DataFrame:
    """A history's rows: commit i is the pool's run of ``seeds[i]``, re-keyed as its own
    result under its own code; from ``k`` on, holweg's figures 2 points lower."""
    by_seed = dict(iter(pool.groupby("seed")))
    parts = []
    for i, seed in enumerate(seeds):
        rows = by_seed[seed].copy()
        rows["key"] = rows["key"] + f"-{i}"
        rows["code_identity"] = f"code-{i}"
        if k is not None and i >= k:
            hit = rows["detector"] == STEPPED
            for name in ("accuracy", "tn_rate", "tp_rate"):
                for end in BOUNDS:
                    rows.loc[hit, f"{name}{end}"] -= STEP
        kept = series_rows(rows)
        kept["commit"], kept["date"] = f"c{i:03d}", f"2026-01-01T{i // 60:02d}:{i % 60:02d}:00Z"
        kept["machine"], kept["bench_digest"], kept["run"] = "study", "", i
        parts.append(kept)
    return pd.concat(parts, ignore_index=True)


def one(pool: pd.DataFrame, h: int, commits: int, stepped: bool, gate: Gate) -> dict:
    rng = rng_for(h, "history-study", stepped)
    seeds = rng.choice(np.sort(pool["seed"].unique()), commits, replace=True)
    k = int(rng.integers(commits // 4, 3 * commits // 4)) if stepped else None
    found = find_steps(history(pool, seeds, k), gate, jobs=1)
    confirmed = found.confirmed
    hit = (
        (confirmed["verdict"] == "regressed")
        & confirmed["series_label"].str.contains(f" · {STEPPED} · ")
        & (confirmed["run"] - (k if k is not None else -10)).abs().le(1)
    )
    return {
        "history": h,
        "step at": "" if k is None else f"c{k:03d}",
        "named": "" if k is None else ("yes" if hit.any() else "no"),
        "named at": ", ".join(sorted(set(confirmed.loc[hit, "commit"]))),
        "series named": int(hit.sum()),
        "false steps": int((~hit).sum()),
        "series": found.series,
        "proposed": len(found.steps),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pool", type=Path, required=True)
    parser.add_argument("--histories", type=int, default=10)
    parser.add_argument("--commits", type=int, default=60)
    parser.add_argument("--out", type=Path)
    a = parser.parse_args()
    pool = read_results(a.pool)
    gate = Gate.of(JUDGED)
    start = time.perf_counter()
    lines = [one(pool, h, a.commits, s, gate) for s in (True, False) for h in range(a.histories)]
    took = time.perf_counter() - start
    table = pd.DataFrame(lines)
    stepped, null = table[table["step at"] != ""], table[table["step at"] == ""]
    named = int((stepped["named"] == "yes").sum())
    false_null = int(null["false steps"].sum())
    per_100 = 100 * false_null / max(1, int(null["series"].sum()))
    text = (
        f"# History steps: a 2-point step in {a.commits} commits\n\n"
        f"Pool: {a.pool.name}, {pool['seed'].nunique()} seeds of the bench then shipped "
        f"({len(pool)} rows: {', '.join(sorted(pool['detector'].unique()))}); gate tolerances "
        f"{dict(gate.tolerances)} (points); seeds drawn per commit with replacement.\n\n"
        f"- step named at k +- 1: {named} of {len(stepped)} histories "
        f"(false steps in them: {int(stepped['false steps'].sum())});\n"
        f"- no step: {false_null} confirmed steps over {int(null['series'].sum())} series "
        f"({per_100:.2f} per 100 series).\n\n"
        f"{table.to_markdown(index=False)}\n\n"
        f"{len(table)} histories in {took:.0f} s on {os.cpu_count()} cores "
        f"(load average {os.getloadavg()[0]:.1f} at the end).\n"
    )
    print(text)
    if a.out:
        a.out.write_text(text)


if __name__ == "__main__":
    main()
