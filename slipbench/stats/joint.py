"""Intervals of averages over cells, from the cells' stored test predictions.

A table that averages cells (the fingers of one sensor, the seeds of one cell) needs the
interval of that average. The fingers of a sensor are recorded in the same trials and the seeds
of a cell draw on the same recordings, so their errors move together: combining their
half-widths as independent understates the interval. Here every averaged group is bootstrapped
once, jointly (:func:`slipbench.stats.metrics.mean_over_test_sets`): each resample draws a trial for
all the group's cells at once. A group some of whose cells lack predictions gets nothing (the
table falls back to the rows, and says so).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from slipbench.errors import DataError
from slipbench.stats.metrics import Predictions, mean_over_test_sets
from slipbench.store.results import read_predictions

JOINT_NOTE = (
    "the interval of a mean over fingers is one bootstrap over the trials the fingers share "
    "(each resample draws a trial for every finger at once)"
)


def _predictions(folders: Sequence[Path], key: str) -> Predictions | None:
    for folder in folders:
        try:
            p = read_predictions(folder, key)
        except (
            DataError
        ) as exc:  # a damaged file costs this group its joint interval, not the report
            warnings.warn(f"{exc}; the tables fall back to the rows' intervals", stacklevel=2)
            return None
        if p is not None:
            score = p["score"].to_numpy()
            groups = (
                p["trial"] if "trial" in p else p["recording_id"]
            )  # a trial shared by fingers is one cluster
            return Predictions(
                p["y_true"].to_numpy().astype(bool),
                score >= 0.5,
                groups.astype(str).to_numpy(),
                score,
            )
    return None


def joint_means(
    rows: pd.DataFrame, by: Sequence[str], folders: Sequence[str | os.PathLike], seed: int = 0
) -> dict[tuple, dict]:
    """Per combination of ``by``: the mean over its finished cells of every figure with one joint
    bootstrap interval (``{figure, figure_lo, figure_hi, ...}``), where every cell of the group
    has its predictions in one of ``folders``."""
    paths = [Path(f) for f in folders]
    ok = rows[rows["status"] == "ok"] if "status" in rows else rows
    out: dict[tuple, dict] = {}
    for key, group in ok.groupby(list(by), sort=False):
        parts = [_predictions(paths, k) for k in group["key"]]
        found = [p for p in parts if p is not None]
        if parts and len(found) == len(parts):
            out[key if isinstance(key, tuple) else (key,)] = mean_over_test_sets(found, seed)
    return out
