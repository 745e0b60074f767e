"""Intervals of averages over cells, from the cells' stored test predictions.

A table that averages cells (the fingers of one sensor, the seeds of one cell) needs the
interval of that average. The fingers of a sensor are recorded in the same trials and the seeds
of a cell draw on the same recordings, so their errors move together: combining their
half-widths as independent understates the interval. Here every averaged group is bootstrapped
once, jointly: each resample draws a trial for all the group's cells at once
(:func:`slipbench.stats.metrics.mean_over_test_sets`). A group run under several seeds
(``--repeats``) gets the two-level bootstrap of :func:`slipbench.stats.metrics.pool_seeds`:
trials drawn once for every seed, and the seeds drawn too, so retraining noise is inside the
interval; each seed's figure is the mean over its cells (fingers). A group some of whose cells
lack predictions, or whose seeds did not all finish the same cells (the seeds' means would
average different fingers), gets nothing: the table falls back to the rows, and says so.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from slipbench.errors import DataError
from slipbench.stats.metrics import Predictions, mean_over_test_sets, pool_seeds
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
    has its predictions in one of ``folders``. A group of several seeds (``n_seeds`` > 1 in the
    result) is the mean over seeds of each seed's mean over its cells, with the two-level
    interval over trials and seeds; it needs every seed to hold the same cells."""
    paths = [Path(f) for f in folders]
    ok = rows[rows["status"] == "ok"] if "status" in rows else rows
    out: dict[tuple, dict] = {}
    for key, group in ok.groupby(list(by), sort=False):
        seeds = _by_seed(group)
        if seeds is None:
            continue
        parts = [[_predictions(paths, k) for k in keys] for keys in seeds]
        found = [[p for p in sets if p is not None] for sets in parts]
        if not all(len(f) == len(sets) for f, sets in zip(found, parts)):
            continue
        key = key if isinstance(key, tuple) else (key,)
        if len(found) > 1:
            out[key] = pool_seeds(found, seed) | {"n_seeds": len(found)}
        else:
            out[key] = mean_over_test_sets(found[0], seed) | {"n_seeds": 1}
    return out


def _by_seed(group: pd.DataFrame) -> list[list[str]] | None:
    """The group's result keys per seed, every seed's in the same order of cells; None where the
    seeds did not finish the same cells (``cell``: the cell's key within its protocol)."""
    if "seed" not in group or group["seed"].nunique() < 2:
        return [list(group["key"])]
    if "cell" not in group:
        return None
    per = []
    for _, g in group.groupby("seed", sort=True):
        if g["cell"].duplicated().any():
            return None
        per.append(dict(zip(g["cell"], g["key"])))
    cells = sorted(per[0])
    if any(sorted(keys) != cells for keys in per):
        return None
    return [[keys[c] for c in cells] for keys in per]
