"""tcn's defaults against a logistic reference: where does it learn, and at what cost.

    python benchmarks/tcn_study.py --dos PATH/TO/biotacsp-dos/csvs [--jobs 2] [--out FILE]

Each setting is a sensor unit, an input (the univariate signal s or the raw channels) and a
window; its windows (non-overlapping, labelled by scenario: what ``slipbench evaluate`` cuts)
are split k-fold with whole recordings (BioTac SP DoS) or trials (the simulation) on one side;
each training fold is balanced to the paper's mix (``slipbench.data.signals.balance``), as a
cell's training side is, and each test fold is scored by balanced accuracy.

The reference is a logistic regression (scikit-learn) on simple features per channel of each
window (mean, standard deviation, mean absolute difference, range, last minus first),
standardized on the training fold. The candidates are tcn settings (``CANDIDATES``): its
defaults before this study, its defaults now, and one change at a time from them. Each fit runs
on one thread (``--jobs`` processes at once), so its seconds compare within this run only, and
"windows trained" (epochs run x windows per epoch) is the cost that does not depend on the
machine. The figures of ``docs/studies/tcn-study.md`` come from this script's ``--out`` file.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

#: tcn's defaults before this study (slipbench 0.1.0 as issue 33 found it)
BEFORE = dict(
    pool="last",
    center=False,
    channels=16,
    blocks=4,
    dropout=0.1,
    windows_per_epoch=None,
    max_epochs=30,
    patience=5,
    batch_size=256,
    learning_rate=3e-3,
)
#: the candidates: name -> tcn parameters (on top of tcn's current defaults)
CANDIDATES: dict[str, dict[str, Any]] = {
    "before": BEFORE,
    "1024 x 30, b256": {
        "windows_per_epoch": 1024,
        "max_epochs": 30,
        "patience": 5,
        "batch_size": 256,
        "learning_rate": 3e-3,
    },
    "now": {},
    "lr 3e-3": {"learning_rate": 3e-3},
    "batch 32": {"batch_size": 32},
    "512 windows/epoch": {"windows_per_epoch": 512},
    "24 epochs": {"max_epochs": 24},
}
#: (dataset, unit, input, window in samples, folds)
SETTINGS = [
    ("dos", "", "channels", 50, 5),
    ("dos", "", "univariate", 50, 5),
    ("sim", "BioTacSP:index", "univariate", 50, 3),
    ("sim", "Nano17:index", "univariate", 50, 3),
]
FEATURES = ("mean", "std", "mean |diff|", "range", "last - first")


def features(x: np.ndarray) -> np.ndarray:
    """(n, window[, channels]) -> (n, 5 * channels): ``FEATURES`` of each channel."""
    x = x[:, :, None] if x.ndim == 2 else x
    return np.concatenate(
        [
            x.mean(1),
            x.std(1),
            np.abs(np.diff(x, axis=1)).mean(1),
            x.max(1) - x.min(1),
            x[:, -1] - x[:, 0],
        ],
        axis=1,
    )


@lru_cache(maxsize=2)  # a process reads each setting's windows once for all its folds
def _windows(dataset: str, unit: str, kind: str, window: int, dos: Path | None):
    """(x, y, groups, Windows) of one setting."""
    from slipbench.data.defaults import default_dataset
    from slipbench.data.read import read_dataset
    from slipbench.data.signals import Signals

    ds = read_dataset(dos) if dataset == "dos" else default_dataset()
    signals = Signals.from_dataset(ds)
    rec = signals.recordings
    names = rec["sensor_type"] + ":" + rec["sensor_instance"].astype(str)
    w = signals.windows(window, np.flatnonzero(names.str.contains(unit, regex=False)))
    x = signals.channel_values(w, window) if kind == "channels" else w.x
    return x, w.y, rec["trial"].to_numpy()[w.recording], w


def _fold(job: tuple) -> list[dict[str, Any]]:
    """The reference and every candidate on one fold of one setting."""
    import torch
    from sklearn.linear_model import LogisticRegression
    from sklearn.metrics import balanced_accuracy_score
    from sklearn.model_selection import GroupKFold
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    from slipbench.data.signals import balance, channel_scales, standardized
    from slipbench.detectors.tcn import TCN
    from slipbench.seeding import rng_for

    setting, fold, candidates, dos = job
    torch.set_num_threads(1)
    x, y, groups, w = _windows(*setting[:4], dos)
    train, test = list(GroupKFold(setting[4]).split(x, y, groups))[fold]
    train = train[balance(w.take(train), rng_for(fold, "tcn-study", *setting[:4]))]
    xtr, xte = x[train], x[test]
    if setting[2] == "channels":  # as the engine gives them: standardized by the training side
        scales = channel_scales(xtr)
        xtr, xte = standardized(xtr, scales), standardized(xte, scales)
    at = dict(zip(("dataset", "unit", "input", "window"), setting[:4]), fold=fold, n=len(train))
    reference = make_pipeline(StandardScaler(), LogisticRegression(max_iter=5000))
    reference.fit(features(xtr), y[train])
    pred = reference.predict(features(xte))
    rows = [{**at, "model": "logistic", "ba": balanced_accuracy_score(y[test], pred)}]
    for name in candidates:
        t0 = time.perf_counter()
        tcn = TCN(**CANDIDATES[name], device="cpu").fit(
            xtr, y[train], seed=fold, groups=groups[train]
        )
        seconds = time.perf_counter() - t0
        per_epoch = tcn.windows_per_epoch or len(train) - len(tcn.validation_y_)
        rows.append(
            {
                **at,
                "model": name,
                "ba": balanced_accuracy_score(y[test], tcn.predict(xte)),
                "seconds": seconds,
                "epochs": tcn.epochs_,
                "windows_trained": tcn.epochs_ * per_epoch,
            }
        )
    return rows


def study(
    dos: Path, candidates: Sequence[str], datasets: Sequence[str], jobs: int, rows_csv: Path | None
) -> pd.DataFrame:
    """Every fold of every setting; each fold's rows appended to ``rows_csv`` as it ends (a
    stopped run keeps what it finished)."""
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        from slipbench.data.importers import biotacsp_dos

        imported = biotacsp_dos(dos, Path(tmp) / "dos")
        jobs_ = [
            (s, f, tuple(candidates), imported)
            for s in SETTINGS
            if s[0] in datasets
            for f in range(s[4])
        ]
        with ProcessPoolExecutor(jobs) as pool:
            for done in as_completed([pool.submit(_fold, job) for job in jobs_]):
                rows += done.result()
                if rows_csv:
                    pd.DataFrame(rows).to_csv(rows_csv, index=False)
    return pd.DataFrame(rows)


def tables(rows: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """Balanced accuracy per setting and model (mean over folds), and each candidate's cost."""
    rows = rows.assign(setting=rows["dataset"] + " " + rows["unit"] + " " + rows["input"])
    rows["setting"] = rows["setting"].str.replace("  ", " ") + " @" + rows["window"].astype(str)
    order = list(dict.fromkeys(rows["model"]))
    accuracy = rows.pivot_table("ba", "setting", "model", sort=False)[order]
    cost = (
        rows.dropna(subset=["seconds"])
        .groupby("model", sort=False)
        .agg(
            seconds=("seconds", "mean"),
            epochs=("epochs", "mean"),
            windows_trained=("windows_trained", "mean"),
        )
    )
    cost["seconds vs now"] = cost["seconds"] / cost.loc["now", "seconds"]
    gap = accuracy[order[1:]].sub(accuracy["logistic"], axis=0)
    cost["mean gap to logistic"] = gap.mean()
    cost["worst gap"] = gap.min()
    return {"accuracy": accuracy, "cost": cost}


def markdown(rows: pd.DataFrame, header: str) -> str:
    t = tables(rows)
    return (
        f"{header}\n\nBalanced accuracy (mean over folds):\n\n"
        f"{t['accuracy'].to_markdown(floatfmt='.3f')}\n\n"
        "Cost per fit (mean over every fold of every setting) and the gap to the logistic "
        f"reference (tcn minus logistic, mean and worst over settings):\n\n"
        f"{t['cost'].to_markdown(floatfmt='.3g')}\n"
    )


def main(argv: Sequence[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dos", type=Path, required=True, help="the BioTac SP DoS csvs folder")
    ap.add_argument("--tables-of", type=Path, help="no fits: the tables of a --rows file")
    ap.add_argument("--candidate", action="append", choices=CANDIDATES, help="default: all")
    ap.add_argument("--dataset", action="append", choices=("dos", "sim"), help="default: both")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, help="write the Markdown here too")
    ap.add_argument("--rows", type=Path, help="write every fold's row here (CSV)")
    a = ap.parse_args(argv)
    if a.tables_of:  # a stopped run's rows, or a finished one's again
        rows = pd.read_csv(a.tables_of, dtype={"unit": str}).fillna({"unit": ""})
        print(markdown(rows, f"tcn study: the rows of {a.tables_of.name}"))
        return
    start = time.perf_counter()
    rows = study(
        a.dos, a.candidate or list(CANDIDATES), a.dataset or ["dos", "sim"], a.jobs, a.rows
    )
    load = os.getloadavg()[0]
    text = markdown(
        rows,
        f"tcn study: {len(rows)} fits, {a.jobs} processes of one thread, "
        f"{time.perf_counter() - start:.0f} s, load average {load:.1f} at the end",
    )
    print(text, flush=True)
    if a.out:
        a.out.write_text(text)


if __name__ == "__main__":
    main()
