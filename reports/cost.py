"""What the reproduction cost, and what it would cost at the paper's size: a Markdown section
for reports/README.md, computed from the results' own rows (reports/reproduce.sh runs it).

Measured, per split and detector: the wall time, as the sum of the gaps between one cell's
finishing and the next (over the whole results folder, in time order), each charged to the cell
that ends it; a gap longer than twice the longest model and a minute is the machine idle between
two sittings of a resumed run, and is left out. Per model: its training time (``train_s``)
plus the inference of its cells (``infer_us_per_window`` x test windows). Extrapolated:

- scale 1.0 (the paper's size) on this machine: the wall time x 1/scale, since every cost of a
  model (training epochs, inference, the bootstrap over test windows) grows with its windows.
  For the LSTM this is an upper bound: its epochs to early stopping fall as the data grow (on
  the window-size protocol, 2.12x the training windows took 1.53x the training time);
- the largest scale whose whole run fits in 2 hours: scale x 2 h / the wall time;
- a dask cluster of 8 such machines (16 workers): the models' costs x 1/scale, each inflated by
  the measured ratio of CPU time (wall x jobs) to the models' own time (data loading, windows,
  bootstrap), scheduled longest first onto the least loaded worker (LPT), whose makespan is
  within 4/3 of the best schedule's.

    python reports/cost.py RESULTS_FOLDER [JOBS]
"""

from __future__ import annotations

import heapq
import sys

import pandas as pd

from slipbench.stats.factors import latest_runs
from slipbench.store.results import read_results

BUDGET_S = 2 * 3600
WORKERS = 8 * 2  # 8 machines of 2 cores


def model_costs(rows: pd.DataFrame) -> pd.DataFrame:
    """Seconds per model: training plus the inference of every cell it tests."""
    ok = rows[rows["status"] == "ok"].copy()
    ok["infer_s"] = ok["infer_us_per_window"].fillna(0) * ok["n_test"].fillna(0) / 1e6
    per = ok.groupby(["split", "detector", "model_key"]).agg(
        train_s=("train_s", "first"), infer_s=("infer_s", "sum")
    )
    return (per["train_s"].fillna(0) + per["infer_s"]).rename("seconds").reset_index()


def makespan(costs: list[float], workers: int) -> float:
    """Longest-processing-time-first schedule of ``costs`` onto ``workers``: the last to finish."""
    loads = [0.0] * workers
    for c in sorted(costs, reverse=True):
        heapq.heapreplace(loads, loads[0] + c)
    return max(loads)


def cost_section(rows: pd.DataFrame, jobs: int) -> str:
    scale = (
        float(rows["dataset_path"].str.extract(r"scale([\d.]+)")[0].astype(float).iloc[0])
        if rows["dataset_path"].str.contains("scale").any()
        else None
    )
    models = model_costs(rows)
    done = pd.to_datetime(rows["finished_at"], format="ISO8601")
    ordered = rows.assign(t=done).sort_values("t")
    gaps = ordered["t"].diff().dt.total_seconds().fillna(0.0)
    idle = max(60.0, 2 * float(models["seconds"].max()))
    wall = gaps.where(gaps <= idle, 0.0).groupby([ordered["split"], ordered["detector"]]).sum()
    per = models.groupby(["split", "detector"])["seconds"].agg(["size", "sum", "max"])
    lines = [
        "| Split | Detector | Models | Wall (min) | In models (CPU min) | Longest model (s) |",
        "|:--|:--|--:|--:|--:|--:|",
    ]
    for (split, detector), w in wall.items():
        p = per.loc[(split, detector)]
        lines.append(
            f"| {split} | {detector} | {int(p['size'])} | {w / 60:.1f} | {p['sum'] / 60:.1f} | {p['max']:.0f} |"
        )
    total = float(wall.sum())
    lines.append(
        f"| **all** | | {len(models)} | **{total / 60:.1f}** | {models['seconds'].sum() / 60:.1f} | "
        f"{models['seconds'].max():.0f} |"
    )
    text = [
        "## What the reproduction cost",
        "",
        f"Measured on this run's machine with `--jobs {jobs}` (wall: the time between cells finishing, idle "
        "time between sittings left out; in models: training plus inference, summed over models):",
        "",
        *lines,
        "",
    ]
    if scale:
        overhead = total * jobs / models["seconds"].sum()
        detectors = per.index.get_level_values("detector").nunique()
        names = list(per.index.unique(level="split"))
        splits = " and ".join(names) + (" splits" if len(names) > 1 else " split")
        cluster = makespan(list(models["seconds"] * overhead / scale), WORKERS)
        text += [
            f"At scale {scale:g} the whole run ({detectors} detectors, every protocol, {splits}) took "
            f"{total / 60:.0f} min. Extrapolated linearly in the data's size (see `reports/cost.py`; an upper bound for the "
            "LSTM, which stops early after fewer epochs on more data): the "
            f"largest scale that fits in 2 hours on this machine is about {scale * BUDGET_S / total:.2f}; scale "
            f"1.0, the paper's size, would take about {total / scale / 3600:.1f} h here, and about "
            f"{cluster / 3600:.1f} h on a dask cluster of 8 such machines (16 workers; the models' costs x "
            f"{1 / scale:g}, inflated by the measured {overhead:.2f} of CPU time per second in models, scheduled "
            f"longest first; the longest single model, {models['seconds'].max() / scale / 60:.0f} min, bounds "
            "it from below).",
            "",
        ]
    return "\n".join(text)


if __name__ == "__main__":
    # a cell run again (after a change of code) costs once: its latest run, as the report counts it
    rows, _ = latest_runs(read_results(sys.argv[1]))
    print(cost_section(rows, int(sys.argv[2]) if len(sys.argv) > 2 else 2))
