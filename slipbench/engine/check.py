"""What a dataset can support, said before anything trains (``slipbench dataset check``).

Per unit: the classes, and the recordings and trials of each; windows available at each size.
Per protocol cell: whether it would run, be skipped (and why), or rest on fewer than
``LOW_N`` test trials of a class, where its intervals are not to be trusted.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from slipbench.data.format import Dataset
from slipbench.data.signals import Signals
from slipbench.engine.plan import CellData, Run, check_labels
from slipbench.errors import UsageError
from slipbench.vocabulary import LOW_N

SIZES = (5, 10, 25, 50, 100, 200)


@dataclass
class DatasetCheck:
    """``units``: one row per unit and class; ``windows``: windows per unit and size;
    ``cells``: one row per protocol cell with its verdict ("runs", "low n", "skipped")."""

    units: pd.DataFrame
    windows: pd.DataFrame
    cells: pd.DataFrame


def _units(signals: Signals, labelling: str) -> pd.DataFrame:
    rec = signals.recordings
    rows = []
    for (sensor, instance), part in rec.groupby(["sensor_type", "sensor_instance"], sort=False):
        windows = signals.windows(50, part.index.to_numpy(), values=False, labelling=labelling)
        for label, name in ((1, "slip"), (0, "non-slip")):
            mine = windows.recording[windows.y == label]
            rows.append(
                {
                    "sensor_type": sensor,
                    "sensor_instance": instance,
                    "class": name,
                    "recordings": len(np.unique(mine)),
                    "trials": rec["trial"].iloc[np.unique(mine)].nunique(),
                    "windows_of_50": len(mine),
                }
            )
    return pd.DataFrame(rows)


def _windows(signals: Signals, labelling: str) -> pd.DataFrame:
    rec = signals.recordings
    rows = []
    for (sensor, instance), part in rec.groupby(["sensor_type", "sensor_instance"], sort=False):
        rate = (
            float(part["unit_rate_hz"].iloc[0])
            if "unit_rate_hz" in part
            else float(part["sampling_rate_hz"].iloc[0])
        )
        row = {"sensor_type": sensor, "sensor_instance": instance, "rate_hz": rate}
        for size in SIZES:
            w = signals.windows(size, part.index.to_numpy(), values=False, labelling=labelling)
            row[f"{size} ({1000 * size / rate:.4g} ms)"] = (
                f"{int((w.y == 1).sum())} / {int((w.y == 0).sum())}"
            )
        rows.append(row)
    return pd.DataFrame(rows)


def _cells(signals: Signals, runs: list[Run]) -> pd.DataFrame:
    rows = []
    trials = signals.recordings["trial"].to_numpy()
    for run in runs:
        data = CellData(signals, run.split, run.seed, run.labels)
        for cell in run.cells(signals.recordings):
            verdict, reason, n_slip, n_non = "runs", "", 0, 0
            try:
                if cell.skip:
                    raise UsageError(cell.skip)
                train, test = data.part(cell.train, cell.window), data.part(cell.test, cell.window)
                for part, role in ((train, "train"), (test, "test")):
                    if len(np.unique(part.y)) < 2:
                        raise UsageError(
                            f"no {'slip' if 1 not in part.y else 'non-slip'} windows to {role} on"
                        )
                n_slip = len(np.unique(trials[test.recording[test.y == 1]]))
                n_non = len(np.unique(trials[test.recording[test.y == 0]]))
                if min(n_slip, n_non) < LOW_N:
                    verdict, reason = (
                        "low n",
                        f"fewer than {LOW_N} test trials of a class: its intervals are not to be trusted",
                    )
            except UsageError as exc:
                verdict, reason = "skipped", str(exc)
            rows.append(
                {
                    "protocol": run.protocol_name,
                    "cell": cell.name,
                    "verdict": verdict,
                    "test_trials_slip": n_slip,
                    "test_trials_nonslip": n_non,
                    "reason": reason,
                }
            )
    return pd.DataFrame(rows)


def check_dataset(dataset: Dataset, runs: list[Run]) -> DatasetCheck:
    """Classes, windows and every cell of ``runs``' protocols on ``dataset``, without training.

    The runs' detectors are not used; their split, seed and labelling are (the first run's for
    the per-unit tables)."""
    labelling = runs[0].labels if runs else "scenario"
    for labels in dict.fromkeys([labelling, *(run.labels for run in runs)]):
        check_labels(labels, dataset)
    signals = Signals.from_dataset(dataset)
    for run in runs:
        for name, values in run.protocol.columns(dataset.recordings).items():
            signals.recordings[name] = values
    return DatasetCheck(
        _units(signals, labelling), _windows(signals, labelling), _cells(signals, runs)
    )
