"""The CSV importer's routes for a logger that is not a sensor's clock: ``[rate] drop_repeats``
drops rows equal to the one before in every channel (a 10 Hz sensor logged at 40 Hz keeps one
row in four), ``[rate] resample_hz`` interpolates each file's rows at a nominal rate from its
time column (a jittery logger, gaps). Both act on a file's rows, so the units a file records
together stay aligned; a row's label goes with it (resampled: the label of the last row at or
before each new time)."""

from __future__ import annotations

from typing import Any

import numpy as np

from slipbench.data.importers.mapping import CsvFile, CsvMapping
from slipbench.errors import DataError


def regular(
    m: CsvMapping,
    file: CsvFile,
    recordings: list[tuple[dict, np.ndarray]],
    labels: np.ndarray | None,
    counted: dict[str, tuple[int, int]] | None = None,
) -> tuple[list[tuple[dict, np.ndarray]], np.ndarray | None]:
    """A file's recordings (metadata row, samples) and labels with its repeated rows dropped
    and/or resampled, as the mapping's ``[rate]`` asks; as they are where it asks neither.
    ``counted`` (file -> rows, rows dropped as repeats) gets this file's where it drops."""
    drop, target = bool(m.rate.get("drop_repeats")), m.rate.get("resample_hz")
    if not (drop or target) or not recordings:
        return recordings, labels
    values = np.hstack([v for _, v in recordings])
    keep = np.ones(len(values), bool)
    if drop:
        keep[1:] = ~np.all(values[1:] == values[:-1], axis=1)
        if counted is not None:  # every row dropped is counted, for the import's warning
            counted[file.rel] = (len(keep), int(len(keep) - keep.sum()))
    if target is None:
        rate = _kept_rate(m, file, keep)
        return (
            [({**row, "sampling_rate_hz": rate}, v[keep]) for row, v in recordings],
            None if labels is None else labels[keep],
        )
    t = np.asarray(file.times, float)[keep]
    grid = np.arange(0.0, t[-1] + 0.5 / target, 1.0 / target)
    grid = grid[grid <= t[-1]]
    if len(grid) < 2:
        raise DataError(
            f"{file.path}: resample_hz = {target:g} leaves {len(grid)} row(s) over its {t[-1]:g} s"
        )
    at = np.searchsorted(t, grid, side="right") - 1  # the last row at or before each time
    out = [
        (
            {**row, "sampling_rate_hz": float(target)},
            np.column_stack([np.interp(grid, t, c) for c in v[keep].astype(np.float64).T]),
        )
        for row, v in recordings
    ]
    return out, None if labels is None else labels[keep][at]


def _kept_rate(m: CsvMapping, file: CsvFile, keep: np.ndarray) -> Any:
    """The rate of a file whose repeated rows were dropped: the one the mapping or the file's
    fields state (the sensor's own), else the median step of the kept rows' times."""
    if "hz" in m.rate or file.fields.get("sampling_rate_hz") is not None or file.times is None:
        return file.rate
    step = float(np.median(np.diff(np.asarray(file.times, float)[keep])))
    return float(f"{1.0 / step:.12g}")
