"""Does a seed move every cell at once? The seed x cell layout of the reduction's changes.

For each detector, split, protocol and sensor type of a results folder run with ``--input both``
and several seeds, the changes channels - univariate of each cell and seed form a seeds x cells
table. A two-way analysis of variance without replication tests the seed's main effect against
the seed-by-cell interaction: a large F says a seed's split moves every cell of the group alike,
so a pooled interval must take the seeds crossed with the cells
(:func:`slipbench.stats.pooled.crossed`), not each cell's seeds on their own. The test noise of
each cell sits in the interaction, so F is the seed's effect over that noise and the cells' own
seed luck.

    python benchmarks/bench_seed_by_cell.py RESULTS_FOLDER
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd
from scipy.stats import f as f_dist

from slipbench.gate.reduction import CHANNELS, RATES, UNIVARIATE, twin_key
from slipbench.store.results import read_results


def seed_by_cell(changes: pd.DataFrame) -> tuple[float, float]:
    """F of the seeds' main effect over the interaction in a (cells, seeds) table, and its p."""
    d = changes.to_numpy(float)
    cells, seeds = d.shape
    grand = d.mean()
    seed_ms = cells * ((d.mean(axis=0) - grand) ** 2).sum() / (seeds - 1)
    rest = d - d.mean(axis=1, keepdims=True) - d.mean(axis=0, keepdims=True) + grand
    rest_df = (seeds - 1) * (cells - 1)
    f = seed_ms / ((rest**2).sum() / rest_df)
    return float(f), float(f_dist.sf(f, seeds - 1, rest_df))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("results", type=Path)
    args = ap.parse_args()
    rows = read_results(args.results)
    rows = rows[rows["status"] == "ok"].copy()
    rows["twin"] = [twin_key(r) for r in rows.to_dict("records")]
    inputs = rows["input"] if "input" in rows else pd.Series(UNIVARIATE, index=rows.index)
    rows["side"] = inputs.fillna(UNIVARIATE)
    lines = []
    groups = ["detector", "split", "protocol", "sensor_type"]
    for key, group in rows.groupby(groups):
        for rate in RATES:
            table = group.pivot_table(index=["twin", "seed"], columns="side", values=rate)
            if not {CHANNELS, UNIVARIATE} <= set(table):
                continue
            changes = (table[CHANNELS] - table[UNIVARIATE]).unstack("seed").dropna()
            if changes.shape[0] < 2 or changes.shape[1] < 2:
                continue
            f, p = seed_by_cell(changes)
            means = " / ".join(f"{100 * m:+.1f}" for m in changes.mean(axis=0))
            lines.append(
                dict(zip(groups, key))
                | {"rate": rate, "cells": changes.shape[0], "seed means": means, "F": f, "p": p}
            )
    print(pd.DataFrame(lines).to_markdown(index=False, floatfmt=".3g"))


if __name__ == "__main__":
    main()
