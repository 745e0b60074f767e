"""Does a seed variance pooled over a protocol's cells narrow the cells' intervals as seeds are
added? The study behind ``seed_pool`` of :func:`slipbench.stats.metrics.over_seeds` and the
section "Seed variance pooled across a protocol's cells" of ``docs/explanation/statistics.md``.

A simulated protocol holds ``CELLS`` cells tested on the same 10 + 10 trials (10-60 windows each)
and two equal detectors (a null: the same model, seeds drawn apart). A window is right with
probability ``expit(a_t + c + u_k,s + e_k,s,t)``: ``a_t ~ N(1.4, 1)`` the trial's difficulty,
``c`` the cell's (window sizes: -0.3 to +0.3), ``u_k,s ~ N(0, SD_SEED^2)`` the retraining luck of
side ``k``'s seed ``s``, shared by the cells (one split, one initialisation per run), and
``e ~ N(0, SD_BY_TRIAL^2)`` the seed's luck on one trial. In the "one noisy cell" scenario the last
cell is also moved by a luck of its own, ``N(0, (NOISY * SD_SEED)^2)`` per seed (a cross-instance
cell that retraining moves more than the rest). Each cell's change in accuracy takes its
simultaneous interval (Bonferroni over the cells, as ``compare`` does) from
:func:`slipbench.stats.metrics.over_seeds`: with each cell's own seeds, with the seed variance
pooled over the protocol's cells (:func:`slipbench.stats.pooled.protocol_seed_pool`) standing for
every cell's (``pool only``, the rule before issue 35's noisy cell, kept here to compare), and with
the pool standing for a side's spread unless the side's own exceeds it beyond the F ratio's
quantile ``q`` (slipbench's rule, at its ``NOISIER_QUANTILE``). Counted per design: the median
degrees of freedom, standard error and width (points), the mean width (a few very wide cells show
there), and the share of protocols where some cell's interval excludes 0 (a false alarm; target <=
5 %).

    nice python benchmarks/bench_seed_pool.py --reps 100 --out benchmarks/results/seed_pool.md
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from unittest import mock

import numpy as np
import pandas as pd

from slipbench.seeding import rng_for
from slipbench.stats import bootstrap
from slipbench.stats.metrics import Predictions, over_seeds
from slipbench.stats.pooled import CellSides, protocol_seed_pool

CELLS = 16
TRIALS = 10  # per class
SD_SEED, SD_BY_TRIAL = 0.15, 0.3
QUANTILES = (0.9, 0.99, 0.999)  # slipbench's NOISIER_QUANTILE among them
NOISY = 8.0  # the noisy cell's own seed SD, in units of SD_SEED (a transfer cell)
ALPHA = 0.05


def _pool_only(reps, at_one, signs, pool):  # type: ignore[no-untyped-def]
    """The rule before: the pool stands for every side's spread, whatever the cell's own."""
    part = sum(t for _, t, _ in reps.seeded)
    if pool is None:
        spread = sum(v for v, _, _ in reps.seeded)
        return max(0.0, spread - part), sum(v**2 / d for v, _, d in reps.seeded)
    spread = sum(k**2 * pool.variance / len(f) for k, f in zip(signs, at_one))
    return max(0.0, spread - part), spread**2 / pool.df


@contextmanager
def rule(name: str) -> Iterator[None]:
    """``pool only``: the rule before; ``pooled q``: a side's own spread kept where it exceeds
    the pool's beyond the F ratio's quantile ``q`` (slipbench's ``NOISIER_QUANTILE``)."""
    if name == "pool only":
        with mock.patch.object(bootstrap, "_seed_variance", _pool_only):
            yield
    elif name.startswith("pooled "):
        with mock.patch.object(bootstrap, "NOISIER_QUANTILE", float(name.split()[1])):
            yield
    else:
        yield


def protocol(rep: int, n_seeds: int, noisy: bool = False) -> list[CellSides]:
    """One simulated protocol of two equal detectors, ``n_seeds`` seeds per side drawn apart;
    ``noisy``: the last cell moved by retraining luck of its own too."""
    rng = rng_for(rep, "bench-seed-pool", noisy)
    n = 2 * TRIALS
    difficulty = rng.normal(1.4, 1.0, n)
    windows = rng.integers(10, 61, n)
    label = np.arange(n) < TRIALS
    luck = rng.normal(0, SD_SEED, (2, n_seeds))
    own = rng.normal(0, NOISY * SD_SEED if noisy else 0.0, (2, n_seeds))
    by_trial = rng.normal(0, SD_BY_TRIAL, (2, n_seeds, n))
    cells = []
    for i, c in enumerate(np.linspace(-0.3, 0.3, CELLS)):
        sides = []
        for k in range(2):
            seeds = []
            for s in range(n_seeds):
                mine = own[k, s] if i == CELLS - 1 else 0.0
                p = 1 / (1 + np.exp(-(difficulty + c + luck[k, s] + mine + by_trial[k, s])))
                hit = rng.random(windows.sum()) < np.repeat(p, windows)
                y = np.repeat(label, windows)
                groups = np.repeat([f"t{t}" for t in range(n)], windows)
                seeds.append(Predictions(y, np.where(hit, y, ~y), groups))
            sides.append(seeds)
        ids = list(range(n_seeds * k, n_seeds * (k + 1)))
        cells.append(CellSides(sides[0], sides[1], list(range(n_seeds)), ids))
    return cells


def one(rep: int, n_seeds: int, how: str, noisy: bool) -> pd.DataFrame:
    """Every cell's change in accuracy of one protocol, at the family's level."""
    cells = protocol(rep, n_seeds, noisy)
    pool = protocol_seed_pool(cells, ("accuracy",)) if how != "own" else None
    level = 1 - ALPHA / CELLS
    rows = []
    for c in cells:
        with rule(how):
            r = over_seeds(c.base, c.cand, rep, level=level, figures=("accuracy",), seed_pool=pool)
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
        ("1 seed per side", 1, "own"),
        ("3 seeds, own", 3, "own"),
        ("3 seeds, pool only", 3, "pool only"),
        *[(f"3 seeds, pooled, own where F > q{q:g}", 3, f"pooled {q}") for q in QUANTILES],
    ]
    out = []
    for noisy in (False, True):
        for name, n_seeds, how in designs:
            runs = [one(rep, n_seeds, how, noisy) for rep in range(reps)]
            out.append(_row(runs, "one noisy cell" if noisy else "alike", name))
    return pd.DataFrame(out)


def _row(runs: list[pd.DataFrame], scenario: str, design: str) -> dict:
    cells = pd.concat(runs)
    return {
        "scenario": scenario,
        "design": design,
        "median df": round(float(cells["df"].median()), 1),
        "median SE (points)": round(float(cells["se"].median()), 2),
        "median width (points)": round(float(cells["width"].median()), 1),
        "mean width (points)": round(float(cells["width"].mean()), 1),
        "protocols with a false alarm": f"{sum(r['excludes_0'].any() for r in runs)} / {len(runs)}",
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=40, help="simulated protocols per design")
    ap.add_argument("--out", type=Path, help="write the table (Markdown) here")
    args = ap.parse_args()
    start = time.perf_counter()
    table = study(args.reps)
    text = (
        f"{CELLS} cells, {TRIALS} + {TRIALS} trials, seed SD {SD_SEED}, seed-by-trial SD "
        f"{SD_BY_TRIAL} (logit), the noisy cell's own seed SD {NOISY * SD_SEED:g}, "
        f"{args.reps} protocols per design, simultaneous 95 % "
        "(Bonferroni over the cells)\n\n" + table.to_markdown(index=False) + "\n"
    )
    print(text)
    print(f"({time.perf_counter() - start:.0f} s)")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)


if __name__ == "__main__":
    main()
