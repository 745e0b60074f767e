"""Why the paper's LSTM did not learn on a real BioTac SP, and what its input scale does.

    python benchmarks/lstm_input_study.py --dos PATH/TO/biotacsp-dos/csvs [--scale 0.02]
        [--jobs 2] [--only NAME ...] [--out FILE]

Every figure is what ``slipbench evaluate`` reports: each candidate runs the window-size
protocol through :func:`slipbench.engine.runner.evaluate` on

- BioTac SP DoS (real, 24 electrodes at 100 Hz, the univariate signal in raw counts), windows
  200, 500 and 1000 ms, grouped split, seeds 0-4;
- the simulated default dataset at ``--scale`` (every unit), windows 10, 50 and 200 samples,
  grouped split, seed 0: where the reproduction in ``reports/`` was measured.

The candidates (``CANDIDATES``) are the LSTM's defaults before this study (the training
windows' 2.5th/97.5th percentiles mapped to [-1, 1]), the input range swept around them, and at
range 1 one change for each other suspect: the paper's epoch cap (100 per stage), a ten times
larger first learning rate, a validation part twice as large. "did not learn" counts the cells
the engine flags (training windows' balanced accuracy indistinguishable from chance).

The input drive is the root mean square over the 80 gate rows of ``w_j * x_t`` over DoS's
training samples at 500 ms (seed 0), at initialization and after training: how far the input
moves a gate's pre-activation (against a forget-gate bias of 1). The results folder keeps each
candidate's models; ``--out`` gets the Markdown tables (benchmarks/results/lstm_input_study.md).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

#: name -> LSTM parameters (everything else at the defaults)
BEFORE = "range 1 (0.1.0)"  # the defaults before this study
CANDIDATES: dict[str, dict[str, Any]] = {
    BEFORE: {"input_range": 1.0},
    "range 0.25": {"input_range": 0.25},
    "range 2": {"input_range": 2.0},
    "range 4 (now)": {"input_range": 4.0},
    "range 8": {"input_range": 8.0},
    "range 16": {"input_range": 16.0},
    "range 1, max_epochs 100": {"input_range": 1.0, "max_epochs": 100},
    "range 1, first rate 0.1": {
        "input_range": 1.0,
        "learning_rates": (0.1, 0.01, 1e-3, 1e-4),
    },
    "range 1, validation 20 %": {"input_range": 1.0, "validation_fraction": 0.2},
}
DOS_WINDOWS, SIM_WINDOWS, SEEDS = ["200ms", "500ms", "1000ms"], [10, 50, 200], range(5)


def _runs(params: dict[str, Any], windows: list, seeds) -> list:
    from slipbench.detectors.lstm import LSTM
    from slipbench.engine.plan import Run
    from slipbench.protocols.window_size import WindowSize

    return [Run(LSTM(**params), WindowSize(windows=windows), "grouped", seed) for seed in seeds]


def _folder(root: Path, name: str) -> Path:
    return root / "".join(c if c.isalnum() else "_" for c in name)


def measure(dos, sim, name: str, folder: Path, jobs: int) -> pd.DataFrame:
    """The rows of one candidate on both datasets, with its wall time per dataset."""
    from slipbench.engine.runner import evaluate
    from slipbench.store.results import ResultsStore

    params, out = CANDIDATES[name], []
    for label, ds, runs in (
        ("dos", dos, _runs(params, DOS_WINDOWS, SEEDS)),
        ("sim", sim, _runs(params, SIM_WINDOWS, [0])),
    ):
        t0 = time.perf_counter()
        store = ResultsStore(_folder(folder, name))
        rows = evaluate(ds, runs, store, jobs=jobs, progress=False)
        out.append(rows.assign(candidate=name, dataset=label, wall_s=time.perf_counter() - t0))
    return pd.concat(out, ignore_index=True)


def drive(dos) -> pd.DataFrame:
    """RMS of w_j x_t over the gate rows and DoS's training samples (500 ms, seed 0), at
    initialization and after training, per input range."""
    from slipbench.detectors.lstm import LSTM
    from slipbench.detectors.lstm_kernels import init_params
    from slipbench.engine.plan import make_plan
    from slipbench.engine.runner import _signals
    from slipbench.seeding import seed_int

    out = []
    for name, params in CANDIDATES.items():
        if not name.startswith("range") or "," in name:
            continue
        run = _runs(params, ["500ms"], [0])[0]
        plan = make_plan(_signals(dos, [run]), [(run, run.cells(dos.recordings))], "", set())
        pc = plan.cells[0]
        train = plan.data_of(pc).values(pc.windows("train"), pc.cell)
        model = LSTM(**params).fit(train.x, train.y, seed=seed_int(0, "detector"))
        xn = (train.x - model.lo_) * model.scale_ - 1.0
        w0 = init_params(model.hidden_size, np.random.default_rng(0))[0]
        out.append(
            {
                "candidate": name,
                "input std": float(xn.std()),
                "drive at init": float(np.sqrt(np.mean(w0**2)) * xn.std()),
                "drive trained": float(np.sqrt(np.mean(model.w_**2)) * xn.std()),
            }
        )
    return pd.DataFrame(out).set_index("candidate")


def tables(rows: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """Per candidate and setting: mean, lowest and highest balanced accuracy over cells and
    seeds, and the cells flagged "did not learn"; the simulated cells against range 1."""
    rows = rows.assign(
        setting=np.where(
            rows["dataset"] == "dos",
            "DoS " + rows["window_ms"].round().astype(int).astype(str) + " ms",
            "sim w" + rows["window"].astype(str),
        ),
        ba=rows["balanced_accuracy"] * 100,
        stuck=rows["warnings"].fillna("").str.startswith("did not learn"),
    )
    order = list(dict.fromkeys(rows["candidate"]))
    grouped = rows.groupby(["candidate", "setting"], sort=False)
    summary = grouped.agg(mean=("ba", "mean"), low=("ba", "min"), stuck=("stuck", "sum"))
    mean = summary["mean"].unstack().loc[order].round(1)
    low = summary["low"].unstack().loc[order].round(1)
    stuck = summary["stuck"].unstack().loc[order].astype(int)
    sim = rows[rows["dataset"] == "sim"]
    base = sim[sim["candidate"] == BEFORE].set_index("key_cell")
    change = []
    for (name, window), group in sim.groupby(["candidate", "window"], sort=False):
        g = group.set_index("key_cell")
        old = base.loc[g.index]
        diff = (g["accuracy"] - old["accuracy"]) * 100
        outside = (g["accuracy"] < old["accuracy_lo"]) | (g["accuracy"] > old["accuracy_hi"])
        change.append(
            {
                "candidate": name,
                "window": window,
                "mean change (points)": round(diff.mean(), 1),
                "lowest": round(diff.min(), 1),
                "highest": round(diff.max(), 1),
                "outside range 1's interval": f"{int(outside.sum())} of {len(g)}",
            }
        )
    cost = rows.groupby(["candidate", "dataset"], sort=False)["wall_s"].first().unstack()
    return {
        "balanced accuracy (%), mean over cells and seeds": mean,
        "lowest balanced accuracy (%) of a cell": low,
        'cells flagged "did not learn"': stuck,
        "simulated data: accuracy against range 1 (0.1.0), cell by cell, per window": pd.DataFrame(
            change
        ).set_index("candidate"),
        "wall seconds per dataset (this run, --jobs workers)": cost.loc[order].round(0),
    }


def _study(args: argparse.Namespace, rows_csv: Path | None) -> pd.DataFrame:
    """Every candidate on both datasets; the rows so far written to ``rows_csv`` after each
    (a stopped run keeps what it finished)."""
    from slipbench.data.defaults import default_dataset
    from slipbench.data.importers import biotacsp_dos
    from slipbench.data.read import read_dataset

    keep = [
        "candidate", "dataset", "sensor_type", "sensor_instance", "window", "window_ms", "seed",
        "balanced_accuracy", "accuracy", "accuracy_lo", "accuracy_hi", "warnings", "epochs",
        "train_s", "wall_s",
    ]  # fmt: skip
    parts = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        dos = read_dataset(biotacsp_dos(args.dos, folder / "dos"))
        sim = default_dataset(args.scale, 0)
        for name in args.only:
            parts.append(measure(dos, sim, name, folder, args.jobs)[keep])
            print(f"{name}: done", flush=True)
            if rows_csv:
                pd.concat(parts, ignore_index=True).to_csv(rows_csv, index=False)
    return pd.concat(parts, ignore_index=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dos", type=Path, required=True, help="the BioTacSP-DoS csvs folder")
    ap.add_argument("--scale", type=float, default=0.02, help="simulated dataset's scale")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", nargs="*", default=list(CANDIDATES), help="candidate names")
    ap.add_argument("--out", type=Path, help="Markdown tables; the rows go beside it (.csv)")
    ap.add_argument("--rows", type=Path, help="render the rows of an earlier run, fit nothing")
    args = ap.parse_args()
    from slipbench.data.importers import biotacsp_dos
    from slipbench.data.read import read_dataset

    rows_csv = args.out.with_suffix(".csv") if args.out else None
    if args.rows:  # the tables again from the rows of an earlier run
        rows = pd.read_csv(args.rows)
    else:
        rows = _study(args, rows_csv)
    rows["key_cell"] = rows["sensor_type"] + ":" + rows["sensor_instance"].astype(str)
    rows["key_cell"] += ":" + rows["window"].astype(str) + ":" + rows["seed"].astype(str)
    with tempfile.TemporaryDirectory() as tmp:
        drives = drive(read_dataset(biotacsp_dos(args.dos, Path(tmp) / "dos")))
    text = [
        f"LSTM input study: BioTac SP DoS ({len(SEEDS)} seeds, grouped) and the simulated "
        f"data (scale {args.scale}, seed 0, grouped)\n"
    ]
    for title, table in tables(rows).items():
        text += [f"\n**{title}**\n", table.to_markdown(), ""]
    text += ["\n**input drive on the gates (DoS 500 ms, seed 0)**\n", drives.round(3).to_markdown()]
    report = "\n".join(text) + "\n"
    print(report)
    if args.out:
        args.out.write_text(report)


if __name__ == "__main__":
    main()
