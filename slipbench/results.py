"""The results store: one Parquet row per (protocol cell, detector, split, seed).

Layout of a results folder::

    cells/<key>.parquet        one finished cell (its row), written atomically
    predictions/<key>.parquet  that cell's test windows: recording, window index, label, score
    models/<model key>.npz     a fitted model (and .json: its training cost), reused by any
                               later cell that trains on the same windows
    results.parquet            every cell row of the folder, rebuilt atomically after each run

A cell's key is a content hash of everything that determines its outcome, so rerunning a
command skips cells already done, and an interrupted run loses at most the cells in flight.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from .errors import DataError

RESULTS_FILE = "results.parquet"


def cell_key(fields: dict[str, Any]) -> str:
    """A stable 20-hex-digit hash of a JSON-able description of a cell."""
    text = json.dumps(fields, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def write_atomic(table: pa.Table, path: Path) -> None:
    """Write a Parquet file so that readers see the old file or the new one, never a torn one."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        pq.write_table(table, tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_text_atomic(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    with os.fdopen(fd, "w") as fh:
        fh.write(text)
    os.replace(tmp, path)


class ResultsStore:
    def __init__(self, folder: str | os.PathLike):
        self.folder = Path(folder)

    def _cell_path(self, key: str) -> Path:
        return self.folder / "cells" / f"{key}.parquet"

    def model_path(self, model_key: str) -> Path:
        """Where the fitted model of a model key is kept, so that later runs reuse it."""
        path = self.folder / "models" / f"{model_key}.npz"
        path.parent.mkdir(parents=True, exist_ok=True)
        return path

    def finished(self) -> dict[str, dict[str, Any]]:
        """Every stored cell row by key: results.parquet, plus cells stored since it was written
        (a run that was killed before rebuilding it). One file read for a consolidated folder."""
        rows: dict[str, dict[str, Any]] = {}
        path = self.folder / RESULTS_FILE
        if path.is_file():
            rows = {r["key"]: r for r in pq.read_table(path).to_pylist()}
        written = {p.stem: p.stat().st_mtime_ns for p in (self.folder / "cells").glob("*.parquet")}
        consolidated = path.stat().st_mtime_ns if path.is_file() else -1
        for key, mtime in written.items():
            if key not in rows or mtime > consolidated:
                rows[key] = pq.read_table(self._cell_path(key)).to_pylist()[0]
        return rows

    def put(self, row: dict[str, Any], predictions: pd.DataFrame | None = None) -> None:
        """Store one finished cell; its predictions first, so a row never lacks them."""
        if predictions is not None:
            write_atomic(pa.Table.from_pandas(predictions, preserve_index=False), self.folder / "predictions" / f"{row['key']}.parquet")
        write_atomic(pa.Table.from_pylist([row]), self._cell_path(row["key"]))

    def consolidate(self) -> Path:
        """Rebuild results.parquet from every finished cell of the folder."""
        rows = self.finished()
        path = self.folder / RESULTS_FILE
        if not rows:
            return path  # nothing finished yet: write no empty results file
        # via pandas: rows of different protocols have different cell columns
        write_atomic(pa.Table.from_pandas(pd.DataFrame(list(rows.values())), preserve_index=False), path)
        return path


def read_results(path: str | os.PathLike) -> pd.DataFrame:
    """Rows of a results file, or of the results.parquet inside a results folder."""
    path = Path(path)
    if path.is_dir():
        path = path / RESULTS_FILE
    if not path.is_file():
        raise DataError(f"{path}: no results file here (run `slipbench evaluate --out FOLDER` first)")
    try:
        rows = pq.read_table(path).to_pandas()
    except (pa.ArrowException, OSError) as exc:
        raise DataError(f"{path}: not a readable results file ({exc})") from None
    missing = {"key", "protocol", "detector", "accuracy"} - set(rows.columns)
    if missing:
        raise DataError(f"{path}: not a slipbench results file (missing columns: {', '.join(sorted(missing))})")
    return rows
