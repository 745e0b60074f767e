"""Power study of `slipbench compare` (issue 20): a drop spread over a protocol must be flagged.

BASE: ``HalfEnergy`` (benchmarks/compare_study.py) on the whole window-size protocol (48 cells,
grouped split, simulated data at scale 0.02). CANDIDATE: the same predictions with, in every
cell, every window of a random ``--trials`` share of the test trials flipped (score 1 - s; about
-4.4 points at 10 %), or a random ``--windows`` share of the windows flipped; drawn anew in each
of ``--runs`` runs. Counted: runs that exit 1, and by which level (pooled, cells). With
``--repeats R`` both sides hold R seeds (the flips drawn per seed).

    nice python benchmarks/bench_compare_power.py [--runs 10] [--repeats 1] [--work DIR]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).parent))
import compare_study as cs  # noqa: E402


def flipped(base: Path, out: Path, rng, trials: float, windows: float) -> Path:
    """A candidate folder: BASE's predictions with the flips, rows with their new accuracy."""
    rows = pd.read_parquet(base / "results.parquet")
    (out / "predictions").mkdir(parents=True)
    for i, row in rows.iterrows():
        p = pd.read_parquet(base / "predictions" / f"{row['key']}.parquet")
        groups = p["trial"] if "trial" in p else p["recording_id"]
        ids = groups.unique()
        hit = groups.isin(ids[rng.random(len(ids)) < trials]) | (rng.random(len(p)) < windows)
        p.loc[hit, "score"] = 1 - p.loc[hit, "score"]
        key = "flip-" + row["key"]
        p.to_parquet(out / "predictions" / f"{key}.parquet")
        correct = (p["score"] >= 0.5) == p["y_true"].astype(bool)
        rows.loc[i, ["key", "accuracy"]] = [key, float(correct.mean())]
    rows.to_parquet(out / "results.parquet")
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--scale", type=float, default=0.02)
    ap.add_argument("--work", type=Path, default=None, help="keep the runs here (reused)")
    args = ap.parse_args()
    root = args.work or Path(tempfile.mkdtemp(prefix="compare-power-"))
    root.mkdir(parents=True, exist_ok=True)
    data, plugins = cs.setup(root, args.scale)
    base = root / f"base-{args.repeats}"
    if not (base / "results.parquet").exists():
        cs.evaluate(data, plugins, base, 0, args.repeats)
    for label, trials, windows in (("10 % of trials", 0.10, 0.0), ("2 % of windows", 0.0, 0.02)):
        t0 = time.perf_counter()
        hits = {"any": 0, "pooled": 0, "cells": 0}
        drops = []
        for run in range(args.runs):
            out = root / f"{label.replace(' ', '')}-{args.repeats}-{run}"
            if not out.exists():
                flipped(base, out, np.random.default_rng(run), trials, windows)
            from slipbench.gate.compare import compare

            cmp = compare(base, out, seed=run)
            hits["any"] += cmp.exit_code == 1
            hits["pooled"] += int(len(cmp.pooled_regressions) > 0)
            hits["cells"] += int(len(cmp.regressions) > 0)
            drops.append(float(cmp.pooled.set_index("figure")["change"]["accuracy"]))
        print(
            f"{label} flipped, {args.repeats} seed(s) per side: exit 1 in {hits['any']} of {args.runs} "
            f"(pooled test {hits['pooled']}, a cell {hits['cells']}); mean change "
            f"{np.mean(drops):+.1f} points (range {min(drops):+.1f} to {max(drops):+.1f}); "
            f"{time.perf_counter() - t0:.0f} s",
            flush=True,
        )


if __name__ == "__main__":
    main()
