"""Does a seed variance pooled over a protocol's cells narrow the cells' intervals as seeds are
added? The study behind ``seed_pool`` of :func:`slipbench.stats.metrics.over_seeds` and the
section "Seed variance pooled across a protocol's cells" of ``docs/statistics.md``.

A simulated protocol holds ``CELLS`` cells tested on the same 10 + 10 trials (10-60 windows each)
and two equal detectors (a null: the same model, seeds drawn apart). A window is right with
probability ``expit(a_t + c + u_k,s + e_k,s,t)``: ``a_t ~ N(1.4, 1)`` the trial's difficulty,
``c`` the cell's (window sizes: -0.3 to +0.3), ``u_k,s ~ N(0, SD_SEED^2)`` the retraining luck of
side ``k``'s seed ``s``, shared by the cells (one split, one initialisation per run), and
``e ~ N(0, SD_BY_TRIAL^2)`` the seed's luck on one trial. Each cell's change in accuracy takes its
simultaneous interval (Bonferroni over the cells, as ``compare`` does) from
:func:`slipbench.stats.metrics.over_seeds`: with each cell's own seeds (before), and with the
seed variance pooled over the protocol's cells (:func:`slipbench.stats.pooled.protocol_seed_pool`,
after). Counted per design: the median degrees of freedom, standard error and width (points), and
the share of protocols where some cell's interval excludes 0 (a false alarm; target <= 5 %).

    nice python benchmarks/bench_seed_pool.py --reps 40 --out benchmarks/results/seed_pool.md
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from slipbench.seeding import rng_for
from slipbench.stats.metrics import Predictions, over_seeds
from slipbench.stats.pooled import CellSides, protocol_seed_pool

CELLS = 16
TRIALS = 10  # per class
SD_SEED, SD_BY_TRIAL = 0.15, 0.3
ALPHA = 0.05


def protocol(rep: int, n_seeds: int) -> list[CellSides]:
    """One simulated protocol of two equal detectors, ``n_seeds`` seeds per side drawn apart."""
    rng = rng_for(rep, "bench-seed-pool")
    n = 2 * TRIALS
    difficulty = rng.normal(1.4, 1.0, n)
    windows = rng.integers(10, 61, n)
    label = np.arange(n) < TRIALS
    luck = rng.normal(0, SD_SEED, (2, n_seeds))
    by_trial = rng.normal(0, SD_BY_TRIAL, (2, n_seeds, n))
    cells = []
    for c in np.linspace(-0.3, 0.3, CELLS):
        sides = []
        for k in range(2):
            seeds = []
            for s in range(n_seeds):
                p = 1 / (1 + np.exp(-(difficulty + c + luck[k, s] + by_trial[k, s])))
                hit = rng.random(windows.sum()) < np.repeat(p, windows)
                y = np.repeat(label, windows)
                groups = np.repeat([f"t{t}" for t in range(n)], windows)
                seeds.append(Predictions(y, np.where(hit, y, ~y), groups))
            sides.append(seeds)
        ids = list(range(n_seeds * k, n_seeds * (k + 1)))
        cells.append(CellSides(sides[0], sides[1], list(range(n_seeds)), ids))
    return cells


def one(rep: int, n_seeds: int, pooled: bool) -> pd.DataFrame:
    """Every cell's change in accuracy of one protocol, at the family's level."""
    cells = protocol(rep, n_seeds)
    pool = protocol_seed_pool(cells, ("accuracy",)) if pooled else None
    level = 1 - ALPHA / CELLS
    rows = []
    for c in cells:
        r = over_seeds(c.base, c.cand, rep, level, figures=("accuracy",), seed_pool=pool)
        rows.append(
            {
                "df": r["df"],
                "se": 100 * r["d_accuracy_se"],
                "width": 100 * (r["d_accuracy_hi"] - r["d_accuracy_lo"]),
                "excludes_0": r["d_accuracy_lo"] > 0 or r["d_accuracy_hi"] < 0,
            }
        )
    return pd.DataFrame(rows)


def study(reps: int) -> pd.DataFrame:
    designs = [
        ("1 seed per side", 1, False),
        ("3 seeds, own", 3, False),
        ("3 seeds, pooled", 3, True),
    ]
    out = []
    for name, n_seeds, pooled in designs:
        runs = [one(rep, n_seeds, pooled) for rep in range(reps)]
        cells = pd.concat(runs)
        out.append(
            {
                "design": name,
                "median df": round(float(cells["df"].median()), 1),
                "median SE (points)": round(float(cells["se"].median()), 2),
                "median width (points)": round(float(cells["width"].median()), 1),
                "protocols with a false alarm": f"{sum(r['excludes_0'].any() for r in runs)} / {reps}",
            }
        )
    return pd.DataFrame(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=40, help="simulated protocols per design")
    ap.add_argument("--out", type=Path, help="write the table (Markdown) here")
    args = ap.parse_args()
    start = time.perf_counter()
    table = study(args.reps)
    text = (
        f"{CELLS} cells, {TRIALS} + {TRIALS} trials, seed SD {SD_SEED}, seed-by-trial SD "
        f"{SD_BY_TRIAL} (logit), {args.reps} protocols per design, simultaneous 95 % "
        "(Bonferroni over the cells)\n\n" + table.to_markdown(index=False) + "\n"
    )
    print(text)
    print(f"({time.perf_counter() - start:.0f} s)")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)


if __name__ == "__main__":
    main()
