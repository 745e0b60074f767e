"""The change in accuracy from one detector to another over the cells both ran: the line to
beat (a detector against the reference) and the change per dataset that the meta-analysis
pools (:mod:`slipbench.stats.meta`).

Two rows are the same cell when they agree in everything but the detector (its parameters and
cell key apart): protocol and its parameters, split, labels, normalization, cell, decimation,
test stream, input, dataset and, for transfer rows, the sensor map. The seeds pair as compare
pairs them, with compare's machinery: where every shared cell has its predictions stored, the
mean change over the cells is one joint cluster bootstrap over the trials they share
(:func:`slipbench.stats.pooled.pooled_change`, seeds crossed with the cells and paired seed by
seed where both sides ran the same); else each cell's change is judged from its rows
(:func:`slipbench.stats.compare.unpaired_cell`) and their mean takes their errors as moving
together (:func:`slipbench.stats.pooled.pooled_from_rows`, the widest case).
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from slipbench.stats.compare import cell_sides, unpaired_cell
from slipbench.stats.metrics import LEVEL
from slipbench.stats.pooled import pooled_change, pooled_from_rows
from slipbench.stats.reduction import find_predictions, inputs, plain

#: what two detectors' rows of one cell share (where the rows hold the column)
CELL_COLUMNS = (
    "protocol",
    "protocol_params",
    "split",
    "labels",
    "normalize",
    "cell",
    "decimation",
    "antialias",
    "test_stream",
    "input",
    "dataset_fingerprint",
    "sensor_map",
)


def cell_of(row: dict) -> str:
    """What a row shares with another detector's row of the same cell, as one text."""
    return json.dumps(
        {c: plain(row[c]) for c in CELL_COLUMNS if c in row}, sort_keys=True, default=str
    )


def _by_cell(rows: pd.DataFrame) -> dict[str, list[dict]]:
    """Finished rows with an accuracy, per cell, each cell's seeds in order."""
    rows = rows.assign(input=inputs(rows))
    if "status" in rows:
        rows = rows[rows["status"] == "ok"]
    if "accuracy" not in rows:
        return {}
    rows = rows[rows["accuracy"].notna()]
    out: dict[str, list[dict]] = {}
    for r in rows.to_dict("records"):
        out.setdefault(cell_of(r), []).append(r)
    for seeds in out.values():
        seeds.sort(key=lambda r: float(plain(r.get("seed")) or -1))
    return out


def _once(rows: list[dict]) -> bool:
    seeds = [plain(r.get("seed")) for r in rows]
    return len(set(seeds)) == len(seeds)


def paired_change(
    base: pd.DataFrame,
    cand: pd.DataFrame,
    folders: Sequence[str | os.PathLike] = (),
    seed: int = 0,
    level: float = LEVEL,
) -> dict:
    """The mean over the cells both ``base`` and ``cand`` finished of (cand - base) accuracy,
    as a fraction, with its interval at ``level`` (module docstring).

    Returns
    -------
    dict
        ``d``, ``lo``, ``hi``, ``se``; ``n_cells`` (0: no cell shared, the rest NaN),
        ``n_skipped`` (shared cells left out: a seed stored twice on a side), ``method``.
    """
    b, c = _by_cell(base), _by_cell(cand)
    shared = [k for k in b if k in c]
    kept = [k for k in shared if _once(b[k]) and _once(c[k])]
    out: dict[str, Any] = {"n_cells": len(kept), "n_skipped": len(shared) - len(kept)}
    if not kept:
        return out | {"d": np.nan, "lo": np.nan, "hi": np.nan, "se": np.nan, "method": ""}
    paths = [Path(f) for f in folders]
    preds = [
        (
            [find_predictions(paths, str(r["key"])) for r in b[k]],
            [find_predictions(paths, str(r["key"])) for r in c[k]],
        )
        for k in kept
    ]
    if all(p is not None for pb, pc in preds for p in (*pb, *pc)):
        parts = [cell_sides(pb, pc, b[k], c[k]) for k, (pb, pc) in zip(kept, preds)]
        res = pooled_change(parts, seed, level)
        how = "joint cluster bootstrap over the trials the cells share"
        how += f", {res['seed_design']}" if res["seeds"] else ""
        return out | {k: float(res[k]) for k in ("d", "lo", "hi", "se")} | {"method": how}
    cells = [unpaired_cell(b[k], c[k], level) for k in kept]
    if not all(np.isfinite(x["d_accuracy_se"]) for x in cells):
        d = float(np.mean([x["d_accuracy"] for x in cells]))
        return out | {
            "d": d,
            "lo": np.nan,
            "hi": np.nan,
            "se": np.nan,
            "method": "no intervals in the rows",
        }
    res = pooled_from_rows(
        [x["d_accuracy"] for x in cells],
        [x["d_accuracy_se"] for x in cells],
        [x.get("df", np.inf) for x in cells],
        level,
    )
    how = "from the rows, the cells' errors taken as moving together (no predictions stored)"
    return out | {k: float(res[k]) for k in ("d", "lo", "hi", "se")} | {"method": how}
