"""How far any interval built from the sample can cover in ``bench_coverage``'s ``heavy`` scenario:
the limit behind the cells of ``docs/studies/coverage.md`` that stay short of 93 %.

In ``heavy`` a trial fails wholesale with probability ``FAIL_SHARE`` (10 %); otherwise it is
drawn exactly as in ``normal``. So a heavy test set that happens to hold no failing trial (a
*clean* one) is distributed exactly as a normal test set, and an interval, a function of the
sample alone, treats the two alike. Its coverage in ``heavy`` is at most

    1 - P(clean) * (1 - c),   c = P_normal(interval holds heavy's truth),

reached only if every test set holding a failing trial is covered. ``P(clean)`` is exact:
``0.9^m`` for a figure of one class (the TP or TN rate and their changes), ``0.9^(2m)`` for one
drawing on both (accuracy, balanced accuracy, AUROC and their changes). ``c`` is measured here on
normal test sets, with the coverage of normal's own truth beside it. Reaching 93 % in ``heavy`` needs
``c >= 1 - 0.07 / P(clean)``: the share of normal test sets whose interval would have to reach a
figure as far off as heavy's (the price of such an interval, paid on clean data).

    nice python benchmarks/bench_coverage_limit.py --reps 1000 --sizes 10,20,40 --jobs 2
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence

import numpy as np
import pandas as pd
from bench_coverage import CHUNK, FAIL_SHARE, NAMES, SCENARIOS, SHORT, dataset, run_tasks, truth
from studies.intervals import method as study_method

from slipbench.stats.bootstrap import DEFAULT_METHOD
from slipbench.stats.metrics import over_seeds

ONE_CLASS = {"tp_rate", "tn_rate", "d_tp_rate", "d_tn_rate"}
TARGET = 0.93


def _chunk(task: tuple[int, int, int, int, str]) -> dict[str, float]:
    """Over ``n`` normal test sets: hits of each interval against normal's and heavy's truth."""
    m, c, n, seed, method = task
    rng = np.random.default_rng([seed, SCENARIOS.index("normal"), m, c])
    own, heavy = truth("normal"), truth("heavy")
    hits = dict.fromkeys([*(f"own_{k}" for k in NAMES), *(f"heavy_{k}" for k in NAMES)], 0.0)
    for r in range(n):
        base, cand = dataset(rng, m, "normal")
        f = over_seeds(base, seed=r, method=study_method(method))
        d = over_seeds(base, cand, seed=r, method=study_method(method))
        for name in NAMES:
            src = d if name.startswith("d_") else f
            lo, hi = src[f"{name}_lo"], src[f"{name}_hi"]
            hits[f"own_{name}"] += bool(lo <= own[name] <= hi)
            hits[f"heavy_{name}"] += bool(lo <= heavy[name] <= hi)
    return hits


def study(
    reps: int, sizes: Sequence[int], jobs: int = 1, seed: int = 0, method: str = DEFAULT_METHOD
) -> pd.DataFrame:
    """One row per (trials per class, figure): ``P(clean)``, ``c``, the bound on heavy's
    coverage and the ``c`` that 93 % would need."""
    tasks = [
        (m, c, min(CHUNK, reps - c * CHUNK), seed, method)
        for m in sizes
        for c in range(-(-reps // CHUNK))
    ]
    results = run_tasks(_chunk, tasks, jobs)
    rows = []
    for m in sizes:
        mine = [h for t, h in zip(tasks, results) if t[0] == m]
        for name in NAMES:
            clean = (1 - FAIL_SHARE) ** (m if name in ONE_CLASS else 2 * m)
            c = sum(h[f"heavy_{name}"] for h in mine) / reps
            rows.append(
                {
                    "trials/class": m,
                    "figure": name,
                    "P(clean)": clean,
                    "normal covers its truth": sum(h[f"own_{name}"] for h in mine) / reps,
                    "c: normal holds heavy's truth": c,
                    "heavy coverage at most": 1 - clean * (1 - c),
                    "c needed for 0.93": max(0.0, 1 - (1 - TARGET) / clean),
                }
            )
    return pd.DataFrame(rows)


def main(argv: Sequence[str] | None = None) -> pd.DataFrame:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reps", type=int, default=1000, help="normal test sets per size")
    ap.add_argument("--sizes", default="10,20,40", help="trials per class, comma list")
    ap.add_argument("--jobs", type=int, default=2, help="processes")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--method",
        default=DEFAULT_METHOD,
        help="interval method (bootstrap.METHODS or studies.intervals.STUDIES)",
    )
    a = ap.parse_args(argv)
    start = time.perf_counter()
    table = study(a.reps, [int(s) for s in a.sizes.split(",")], a.jobs, a.seed, a.method)
    short = {**SHORT, **{f"d_{k}": f"d {v}" for k, v in SHORT.items()}}
    shown = table.assign(figure=table["figure"].map(short))
    print(
        f"{a.reps} normal test sets per size, method {a.method}, seed {a.seed}, "
        f"{time.perf_counter() - start:.0f} s\n\n{shown.to_markdown(index=False, floatfmt='.3f')}\n",
        flush=True,
    )
    return table


if __name__ == "__main__":
    main()
