"""The Xela uSkin pick-and-move recordings of imanlab/proactive-slip-control (MIT): a Franka
Panda moves a box held by two uSkin 4x4 pads, per-sample slip labels from a wrist camera."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from slipbench.data.health import TIMING_KEY, timing, timing_summary
from slipbench.data.importers.tables import column_numbers, read_csv
from slipbench.data.write import write_dataset
from slipbench.errors import DataError
from slipbench.vocabulary import SENSOR_TYPE

CSV = {"delimiter": ",", "comment": None, "skip_rows": 0}
PADS = {"pad1": "xela_sensor1.csv", "pad2": "xela_sensor2.csv"}
N_CHANNELS = 48  # 16 taxels x (x, y, z)
SOURCE = "imanlab/proactive-slip-control (commit 73c84b0), data_set/{trial}"


def _column(frame: pd.DataFrame, column: str, path: Path) -> np.ndarray:
    if column not in frame.columns:
        raise DataError(f"{path}: no column {column!r} (columns: {', '.join(frame.columns)})")
    return column_numbers(frame, column, path, CSV)


def _labels(path: Path, n: int) -> np.ndarray:
    """``slip`` as int8; samples after a failed grasp (``fail`` 1: the box is lost) are
    unlabelled (-1), as the format marks a drop."""
    frame = read_csv(path, CSV, [])
    slip, fail = _column(frame, "slip", path), _column(frame, "fail", path)
    for name, values in (("slip", slip), ("fail", fail)):
        bad = ~np.isin(values, (0, 1))
        if bad.any():
            row = int(np.argmax(bad))
            raise DataError(
                f"{path}: row {row + 1}: column {name!r}: {values[row]!r} is not 0 or 1"
            )
    if len(slip) != n:
        raise DataError(f"{path}: {len(slip)} labels, but the pads' files hold {n} samples")
    labels = slip.astype(np.int8)
    labels[fail == 1] = -1
    return labels


def _rate(path: Path) -> float:
    frame = read_csv(path, CSV, [], min_rows=1, text=True)
    if len(frame) != 1:
        raise DataError(f"{path}: {len(frame)} rows; meta_data.csv holds one")
    rate = (
        float(pd.to_numeric(frame["frequency_hz"], errors="coerce").iloc[0])
        if ("frequency_hz" in frame.columns)
        else float("nan")
    )
    if not (np.isfinite(rate) and rate > 0):
        raise DataError(f"{path}: column 'frequency_hz' must hold a rate > 0 in Hz")
    return rate


def _clock(path: Path, n: int) -> np.ndarray:
    """The rows' own clock: ``robot_state.csv``'s ``time`` (s from the first row), one per row
    of the pads' files, increasing."""
    t = _column(read_csv(path, CSV, []), "time", path).astype(np.float64)
    if len(t) != n:
        raise DataError(f"{path}: {len(t)} rows, but the pads' files hold {n}; one clock per row")
    if (np.diff(t) <= 0).any():
        row = int(np.argmax(np.diff(t) <= 0)) + 1
        raise DataError(f"{path}: row {row + 1}: column 'time' does not increase")
    return t - t[0]


def xela_proactive(
    src: str | Path, out: str | Path, description: Mapping[bytes, str] | None = None
) -> Path:
    """Import the ``data_set`` folder of imanlab/proactive-slip-control.

    Each ``data_sample_*`` folder is one trial: ``xela_sensor1.csv`` and ``xela_sensor2.csv``
    become recordings ``<folder>/pad1`` and ``<folder>/pad2`` (sensor ``XelaUSkin``, the 48
    columns of the header, unit ``count``) of that trial, at the rate ``meta_data.csv`` gives
    (``frequency_hz``; the seven trials' rates spread 0.4 %, within ``RATE_TOLERANCE``), which
    ``robot_state.csv``'s per-row ``time`` bears out (its steps, gaps and any disagreement with
    the stated rate are kept as the CSV importer keeps a time column's, and said by
    ``dataset validate``, ``info`` and ``check``); the labels are ``slip_label.csv``'s ``slip``, unlabelled where ``fail`` is 1. One object (material
    ``box``), speed unknown, scenario ``hold-slip``. ``description`` goes to the metadata.
    """
    src = Path(src)
    trials = sorted(p for p in src.glob("data_sample_*") if p.is_dir())
    if not trials:
        raise DataError(f"{src}: no data_sample_* folder (give the repository's data_set folder)")
    rows, samples, labels = [], {}, {}
    timings = {}
    for folder in trials:
        rate = _rate(folder / "meta_data.csv")
        pads = {}
        for pad, name in PADS.items():
            frame = read_csv(folder / name, CSV, [])
            if frame.shape[1] != N_CHANNELS:
                raise DataError(f"{folder / name}: {frame.shape[1]} columns; a uSkin pad has 48")
            pads[pad] = frame
        n = {len(f) for f in pads.values()}
        if len(n) != 1:
            raise DataError(
                f"{folder}: the pads' files hold {sorted(n)} rows; one trial, one length"
            )
        rows_n = n.pop()
        slip = _labels(folder / "slip_label.csv", rows_n)
        timings[folder.name] = timing(_clock(folder / "robot_state.csv", rows_n), rate)
        for pad, frame in pads.items():
            rid = f"{folder.name}/{pad}"
            path = folder / PADS[pad]
            samples[rid] = np.column_stack([_column(frame, c, path) for c in frame.columns])
            labels[rid] = slip
            rows.append(
                {
                    "recording_id": rid,
                    SENSOR_TYPE: "XelaUSkin",
                    "sensor_instance": pad,
                    "scenario": "hold-slip",
                    "material": "box",
                    "speed_mm_s": None,
                    "sampling_rate_hz": rate,
                    "channels": tuple(str(c) for c in frame.columns),
                    "units": ("count",) * N_CHANNELS,
                    "source": SOURCE.format(trial=folder.name),
                    "trial": folder.name,
                }
            )
    description = {**(description or {}), TIMING_KEY.encode(): json.dumps(timing_summary(timings))}
    return write_dataset(out, pd.DataFrame(rows), samples, labels, description=description)
