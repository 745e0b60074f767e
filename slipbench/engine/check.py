"""What a dataset can support, said before anything trains (``slipbench dataset check``).

Per unit and window length the protocols use: the classes, and the recordings, trials and
windows of each.
Per protocol cell: whether it would run, be skipped (and why), or rest on fewer than
``LOW_N`` test trials of a class, where its intervals are not to be trusted; the windows of each
class it uses of those its sides could hold before balancing, and a warning where balancing
keeps under half of a class.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from slipbench.data.format import Dataset
from slipbench.data.signals import Signals, Windows
from slipbench.engine.plan import CellData, Run, check_labels
from slipbench.errors import UsageError
from slipbench.protocol import NO_CELL_KEY, Cell, unit_rate
from slipbench.stats.metrics import classes_low_n
from slipbench.vocabulary import LOW_N, SENSOR_TYPE

SIZES = (5, 10, 25, 50, 100, 200)  # the window table's sizes where no protocol cell names one
WINDOW_COLUMNS = [
    SENSOR_TYPE,
    "sensor_instance",
    "rate_hz",
    "window",
    "window_ms",
    "slip",
    "non_slip",
    "used_by",
]
KEPT_COLUMNS = ["train_slip", "train_nonslip", "test_slip", "test_nonslip"]
CELL_COLUMNS = [
    "protocol",
    "cell",
    "verdict",
    "test_trials_slip",
    "test_trials_nonslip",
    "reason",
    *KEPT_COLUMNS,
    "balance_warning",
]


@dataclass
class DatasetCheck:
    """``units``: one row per unit, window length the protocols use and class (columns
    :data:`UNIT_COLUMNS`); ``windows``: slip and non-slip windows per unit
    and window length the protocols use (columns :data:`WINDOW_COLUMNS`); ``cells``: one row
    per protocol cell with its verdict ("runs", "low n", "skipped"), a protocol that makes no
    cell on the dataset as one skipped row saying why."""

    units: pd.DataFrame
    windows: pd.DataFrame
    cells: pd.DataFrame


UNIT_COLUMNS = [
    SENSOR_TYPE,
    "sensor_instance",
    "window",
    "class",
    "recordings",
    "trials",
    "windows",
]


def _used(
    recordings: pd.DataFrame, runs: list[tuple[Run, list[Cell]]]
) -> dict[tuple[tuple[str, str], int], list[str]]:
    """(unit, window in samples) -> the protocols whose cells use it; every unit at the sizes
    of :data:`SIZES` where no cell names a window."""
    used: dict[tuple[tuple[str, str], int], list[str]] = {}
    for run, cells in runs:
        for cell in cells:
            if cell.key == NO_CELL_KEY:
                continue
            for unit in dict.fromkeys((*cell.train.sensors, *cell.test.sensors)):
                names = used.setdefault((unit, cell.window), [])
                if run.protocol_name not in names:
                    names.append(run.protocol_name)
    if not used:
        units = recordings[[SENSOR_TYPE, "sensor_instance"]].drop_duplicates()
        used = {
            (u, size): ["—"] for u in units.itertuples(index=False, name=None) for size in SIZES
        }
    return used


def _units(
    signals: Signals, labelling: str, used: dict[tuple[tuple[str, str], int], list[str]]
) -> pd.DataFrame:
    """Per unit, window length the runs use and class: the recordings, trials and windows
    holding it. Labelled from the samples, a class depends on the window (a majority of slip
    samples), so each length the protocols ask for is counted, not one fixed size."""
    rec = signals.recordings
    rows = []
    for (sensor, instance), part in rec.groupby([SENSOR_TYPE, "sensor_instance"], sort=False):
        for size in sorted(w for u, w in used if u == (sensor, instance)):
            windows = signals.windows(
                size, part.index.to_numpy(), values=False, labelling=labelling
            )
            for label, name in ((1, "slip"), (0, "non-slip")):
                mine = windows.recording[windows.y == label]
                rows.append(
                    {
                        SENSOR_TYPE: sensor,
                        "sensor_instance": instance,
                        "window": size,
                        "class": name,
                        "recordings": len(np.unique(mine)),
                        "trials": rec["trial"].iloc[np.unique(mine)].nunique(),
                        "windows": len(mine),
                    }
                )
    return pd.DataFrame(rows, columns=UNIT_COLUMNS)


def _windows(
    signals: Signals, labelling: str, used: dict[tuple[tuple[str, str], int], list[str]]
) -> pd.DataFrame:
    """Slip and non-slip windows before balancing, once per unit and window length the runs'
    cells use (in samples at the unit's full rate, and in ms), with the protocols that use it;
    the sizes of :data:`SIZES` where no cell names a window."""
    rec = signals.recordings
    units = list(rec.groupby([SENSOR_TYPE, "sensor_instance"], sort=False).groups.items())
    rows = []
    for unit, index in units:
        rate = unit_rate(rec, unit)
        for size in sorted(w for u, w in used if u == unit):
            w = signals.windows(size, np.asarray(index), values=False, labelling=labelling)
            rows.append(
                {
                    SENSOR_TYPE: unit[0],
                    "sensor_instance": unit[1],
                    "rate_hz": rate,
                    "window": size,
                    "window_ms": round(1000.0 * size / rate, 1),
                    "slip": int((w.y == 1).sum()),
                    "non_slip": int((w.y == 0).sum()),
                    "used_by": ", ".join(used[unit, size]),
                }
            )
    return pd.DataFrame(rows, columns=WINDOW_COLUMNS)


def _cells(signals: Signals, runs: list[tuple[Run, list[Cell]]]) -> pd.DataFrame:
    rows = []
    trials = signals.recordings["trial"].to_numpy()
    for run, cells in runs:
        data = CellData(signals, run.split, run.seed, run.labels, balancing=run.balance)
        for cell in cells:
            verdict, reason, n_slip, n_non = "runs", "", 0, 0
            kept, warning = dict.fromkeys(KEPT_COLUMNS, ""), ""
            try:
                if cell.skip:
                    raise UsageError(cell.skip)
                train, test = data.part(cell.train, cell.window), data.part(cell.test, cell.window)
                kept, warning = _kept(data, cell, {"train": train, "test": test})
                for part, role in ((train, "train"), (test, "test")):
                    if len(np.unique(part.y)) < 2:
                        raise UsageError(
                            f"no {'slip' if 1 not in part.y else 'non-slip'} windows to {role} on"
                        )
                n_slip = len(np.unique(trials[test.recording[test.y == 1]]))
                n_non = len(np.unique(trials[test.recording[test.y == 0]]))
                if classes_low_n(n_slip, n_non):
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
                    **kept,
                    "balance_warning": warning,
                }
            )
    return pd.DataFrame(rows, columns=CELL_COLUMNS)


def _kept(data: CellData, cell: Cell, sides: dict[str, Windows]) -> tuple[dict[str, str], str]:
    """Per side and class, the windows a cell uses of those it could hold before balancing
    ("52 of 930"), and its balancing warning ("" where it kept at least half of each)."""
    kept = {}
    for role, windows in sides.items():
        part = cell.train if role == "train" else cell.test
        could = data.available(part, cell.window)
        for c, name in ((1, "slip"), (0, "nonslip")):
            kept[f"{role}_{name}"] = f"{int((windows.y == c).sum())} of {could[c]}"
    return kept, data.balance_warning(cell, sides)


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
    planned = [(run, run.cells_or_stand_in(signals.recordings)) for run in runs]
    used = _used(signals.recordings, planned)
    return DatasetCheck(
        _units(signals, labelling, used),
        _windows(signals, labelling, used),
        _cells(signals, planned),
    )
