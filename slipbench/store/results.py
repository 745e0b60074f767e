"""The results store: one Parquet row per (protocol cell, detector, split, seed).

Layout of a results folder::

    cells/<key>.parquet        one finished cell (its row), written atomically: the source of truth
    predictions/<key>.parquet  that cell's test windows: recording, window index, label, score
    models/<model key>.npz     a fitted model (and .json: its training cost), reused by any
                               later cell that trains on the same windows
    results.parquet            every cell row of the folder in one file, rebuilt when cells change
    .lock                      taken while results.parquet is rebuilt

A cell's key is a content hash of everything that determines its outcome
(:func:`slipbench.store.keys.cell_key`), so rerunning a command skips cells already done, and an
interrupted run loses at most the cells in flight.

What survives what:

- *A killed run* (even ``kill -9``): every cell it finished is in ``cells/``, whole, and
  :func:`read_results` and :meth:`ResultsStore.finished` read them whether or not
  ``results.parquet`` was rebuilt.
- *A rerun with nothing new*: writes nothing, so it works on a read-only folder.
  ``results.parquet`` records, in its Parquet metadata, which version (size, mtime, inode) of
  each cell file it holds; a cell file whose version differs is read again, and the file is
  rewritten only when a row actually changed.
- *Two runs on one folder*: cells are written without coordination (each write is atomic,
  distinct keys never touch); rebuilding ``results.parquet`` takes the folder's lock and reads
  the folder again under it, so neither run's rows are lost.
- *A full disk, a read-only folder, a missing permission*: an
  :class:`~slipbench.errors.EnvironmentFault` (exit 5) naming the path; no partial file is left.
- *A flipped bit, a damaged file, an edit*: every row carries its digest, in its cell file and in
  results.parquet, and results.parquet a digest of its whole table besides
  (:mod:`slipbench.store.digests`), checked on every read; what fails them is refused by name,
  or computed again by a run (:mod:`slipbench.store.scan`); a run never copies a row it has not
  proved.
"""

from __future__ import annotations

import json
import os
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa

from slipbench.atomic import (
    RESULTS_CELLS,
    check_writable,
    folder_lock,
    make_folder,
    open_parquet,
    whole_text,
    write_atomic,
    write_text_atomic,
)
from slipbench.errors import CellsFailed, DataError
from slipbench.store.columns import checked
from slipbench.store.digests import (
    digests_of,
    failing,
    proved_whole,
    row_digest,
    with_digests,
    with_table_digest,
    written_digests,
)
from slipbench.store.keys import cell_key
from slipbench.store.scan import (
    MANIFEST,
    RESULTS_FILE,
    UNPROVEN,
    Cell,
    Rows,
    Scan,
    cell_entries,
    check_ranges,
    read_cell,
    read_error,
    read_table,
    rows_of,
    same,
    same_row,
    scan,
    version,
)

__all__ = [
    "RESULTS_FILE",
    "REQUIRED_COLUMNS",
    "ResultsStore",
    "read_results",
    "read_predictions",
    "results_folder",
    "cells_failed",
    "cell_key",
    "row_digest",
    "write_atomic",
    "write_text_atomic",
]

#: columns every results row has, whatever its status (metrics exist only for cells that ran)
REQUIRED_COLUMNS = ("key", "protocol", "detector", "status")
MISMATCHES_NAMED = 3  # rows named in the message about a results file that does not match


class ResultsStore:
    """A results folder (see the module's docstring for its layout and guarantees)."""

    def __init__(self, folder: str | os.PathLike):
        self.folder = Path(folder)
        self._seen: Scan | None = None  # the latest scan: what it proved is not proved again
        # the cell files this store wrote, as written: a scan does not read them back
        self._written: dict[str, Cell] = {}

    def _cell_path(self, key: str) -> Path:
        return self.folder / RESULTS_CELLS / f"{key}.parquet"

    def model_path(self, model_key: str) -> Path:
        """Where the fitted model of a model key is kept, so that later runs reuse it."""
        return make_folder(self.folder / "models") / f"{model_key}.npz"

    def check_writable(self, unless_stored: bool = False) -> None:
        """Raise EnvironmentFault (exit 5, naming the folder) unless cells can be written here;
        creates nothing. With ``unless_stored``, a folder that holds cells passes: a rerun that
        finds them all writes nothing, and the run checks again once it knows what it writes."""
        check_writable(self.folder, RESULTS_CELLS if unless_stored else "")

    def finished(self) -> dict[str, dict[str, Any]]:
        """Every stored cell row that proves itself, by key: results.parquet, plus cells stored
        since it was written.

        One file read and one ``stat`` per cell for a consolidated folder. What cannot be
        proved (a damaged cell file, a row that fails its digest, a file without digests) is
        left out with a warning naming it, so that a run computes that cell again and replaces
        the file; a damaged results.parquet is read from ``cells/`` instead.
        """
        self._seen = scan(self.folder, known=self._seen, written=self._written)
        for note in self._seen.notes:
            warnings.warn(note, stacklevel=2)
        return self._seen.rows()

    def cell(self, key: str) -> dict[str, Any] | None:
        """The stored row of one cell that proves itself (None: not stored, or not proved, with
        a warning naming the file): where another process (an array task on another node)
        wrote it."""
        path = self._cell_path(key)
        if not path.exists():
            return None
        try:
            cell = read_cell(path, key)
        except DataError as exc:
            warnings.warn(str(exc), stacklevel=2)
            return None
        return cell.row if cell.proven else None

    def put(self, row: dict[str, Any], predictions: pd.DataFrame | None = None) -> None:
        """Store one finished cell (its columns those of :mod:`slipbench.store.columns`), with
        its digest; its predictions first, so a row never lacks them."""
        checked(row)
        if predictions is not None:
            write_atomic(
                pa.Table.from_pandas(predictions, preserve_index=False),
                self.folder / "predictions" / f"{row['key']}.parquet",
            )
        table = pa.Table.from_pylist([row])
        # the digest of the row as it reads back (pyarrow's types), which readers recompute
        back = table.to_pylist()
        path = self._cell_path(row["key"])
        write_atomic(with_digests(table, digests_of(back)), path)
        try:
            self._written[row["key"]] = Cell(back[0], version(path.stat()), True)
        except OSError:  # gone already (another run's rewrite): a scan reads what is there
            self._written.pop(row["key"], None)

    def consolidate(self) -> Path:
        """Rebuild results.parquet from every proved row, if any row changed (or one there
        fails its digest); returns its path.

        A folder whose results.parquet is up to date is only read (no lock, no write). Otherwise
        the folder's lock is taken and the folder read again under it, so that a concurrent run's
        cells are never dropped.
        """
        path = self.folder / RESULTS_FILE
        self._seen = scan(self.folder, known=self._seen, written=self._written)
        if not self._seen.changed:
            return path
        with folder_lock(self.folder):
            found = self._seen = scan(self.folder, known=self._seen, written=self._written)
            if found.changed:
                manifest = json.dumps(found.versions, separators=(",", ":"), sort_keys=True)
                table = with_digests(found.combined(self.folder), found.row_digests())
                metadata = {**(table.schema.metadata or {}), MANIFEST: manifest.encode()}
                write_atomic(with_table_digest(table.replace_schema_metadata(metadata)), path)
        return path


def _check_file(table: pa.Table, path: Path) -> None:
    """Refuse a results file whose rows are not those slipbench wrote (rows deleted, added or
    edited, columns swapped): by the row digests written in its metadata, else, beside a cells/
    folder, by the cell files; warn where cells/ holds cells the file lacks (a run since).
    A file without digests (another tool, an older slipbench) has its figures checked against
    the results schema, and a warning says that edits to it cannot be detected. A file proved
    whole by its table digest has its rows checked no further.

    Raises
    ------
    DataError
        Naming what does not match: how many rows, and the first of them with their columns;
        or the first figure out of its column's range.
    """
    cells = path.parent / "cells"
    digests = written_digests(table, path)
    if digests is not None and proved_whole(table):
        _warn_stale(table, path, cells, Rows(table, path))
        return
    here = {str(r.get("key")): r for r in rows_of(table, path)}
    if digests is not None:
        changed = failing([r for k, r in here.items() if k in digests], digests)
        lost, added = sorted(set(digests) - set(here)), sorted(set(here) - set(digests))
    elif cells.is_dir():  # its cell files are the reference
        changed = [k for k, r in here.items() if _cell_differs(cells, k, r)]
        lost, added = [], [k for k in here if not (cells / f"{k}.parquet").is_file()]
    else:
        changed, lost, added = [], [], []
    problems = [
        f"{len(keys)} row(s) {what} (e.g. {', '.join(keys[:MISMATCHES_NAMED])})"
        for keys, what in ((lost, "written to it are missing"), (added, "slipbench did not write"))
        if keys
    ]
    if changed:
        named = "; ".join(
            f"row {k}: {_cell_says(cells, k, here[k])}" for k in changed[:MISMATCHES_NAMED]
        )
        problems.insert(0, f"{len(changed)} row(s) edited since they were written ({named})")
    if problems:
        fix = (
            "give the folder instead (its cells/ hold each cell as it was computed)"
            if cells.is_dir()
            else "use the results folder it came from, or rerun"
        )
        raise DataError(
            f"{path}: its rows are not what slipbench wrote: {'; '.join(problems)}; {fix}"
        )
    if digests is None:
        check_ranges(list(here.values()), path)
        warnings.warn(
            f"{path}: carries no row digests ({UNPROVEN}): its figures are checked against the "
            "results schema, but edits to it cannot be detected",
            stacklevel=3,
        )
    _warn_stale(table, path, cells, here)


def _warn_stale(
    table: pa.Table, path: Path, cells: Path, here: Mapping[str, dict[str, Any]]
) -> None:
    """Warn where ``cells`` holds cells the results file ``path`` lacks or holds otherwise (a
    run since it was written)."""
    stale = _stale_cells(table, cells, here)
    if stale:
        warnings.warn(
            f"{path}: {len(stale)} finished cell(s) of {cells} are not in this file as they are now "
            f"(e.g. {stale[0]}: a run since it was written, or one stopped before it was rebuilt); "
            "give the folder to read them",
            stacklevel=4,
        )


def _stale_cells(table: pa.Table, cells: Path, here: Mapping[str, dict[str, Any]]) -> list[str]:
    """The cells of ``cells`` a results file lacks, or holds otherwise than the cell file says
    now (read where its metadata records another version of the file: a copied folder's cells
    are read, not taken for changed)."""
    try:
        held = json.loads((table.schema.metadata or {}).get(MANIFEST, b"{}"))
    except ValueError:
        held = {}
    out = []
    for entry in cell_entries(cells):
        key = entry.name[: -len(".parquet")]
        if key not in here:
            out.append(key)
            continue
        try:
            now = version(entry.stat())
        except FileNotFoundError:
            continue
        if held.get(key, now) != now and _cell_differs(cells, key, here[key]):
            out.append(key)
    return sorted(out)


def _cell_differs(cells: Path, key: str, row: dict[str, Any]) -> bool:
    """Whether a results file's row says otherwise than its cell file (False where none is)."""
    if not (cells / f"{key}.parquet").is_file():
        return False
    try:
        cell = read_cell(cells / f"{key}.parquet", key)
    except DataError:
        return True
    return not same_row(cell.row, row)


def _shown(value: Any) -> str:
    return f"{value:.6g}" if isinstance(value, float) else repr(value)


def _cell_says(cells: Path, key: str, row: dict[str, Any]) -> str:
    """How a results file's row differs from its cell file (the columns, with both values), or
    that it differs from what was written, where no readable cell file says more."""
    try:
        cell = read_cell(cells / f"{key}.parquet", key).row
    except DataError:
        return "its content is not what was written"
    columns = sorted(
        {k for k, v in cell.items() if not same(v, row.get(k))}
        | {k for k, v in row.items() if k not in cell and v is not None}
    )
    shown = ", ".join(
        f"{c} {_shown(row.get(c))} here, {_shown(cell.get(c))} in cells/" for c in columns[:4]
    )
    return shown + (f" and {len(columns) - 4} more columns" if len(columns) > 4 else "")


def read_results(path: str | os.PathLike) -> pd.DataFrame:
    """Rows of a results file, or of every finished cell of a results folder, each proved by
    its digest.

    A folder is read as :meth:`ResultsStore.finished` reads it, so the cells of a run that was
    killed before rebuilding results.parquet are there; a cell file that cannot be read or
    proved is a DataError naming it, a damaged results.parquet is read from ``cells/`` with a
    warning. What carries no digests (another tool, an older slipbench) has its figures checked
    against the results schema, a warning says that edits to it cannot be detected, and the
    rows' ``attrs["unproven"]`` names it (for the report), and ``attrs["unproven_keys"]`` the
    keys of its rows (for the history). Raises DataError when there is nothing to read or a
    required column is missing.
    """
    path = Path(path)
    if path.is_dir():
        found = scan(path, strict=True)
        for note in found.notes:
            warnings.warn(note, stacklevel=2)
        rows, unproven = found.frame(), found.unproven
        keys = [Path(p).stem for p in found.unproven if Path(p).parent.name == "cells"]
        if found.results.unproven:  # results.parquet's rows that no cell file replaced
            keys += [k for k in found.results.rows if k not in found.newer]
        if rows.empty:
            raise DataError(
                f"{path}: no results here (run `slipbench evaluate --out FOLDER` first)"
            )
    elif path.is_file():
        table = read_table(path)
        _check_file(table, path)
        rows = table.to_pandas()
        unproven = [] if written_digests(table, path) is not None else [str(path)]
        keys = [str(k) for k in rows["key"]] if unproven and "key" in rows else []
    else:
        raise DataError(
            f"{path}: no results file here (run `slipbench evaluate --out FOLDER` first)"
        )
    missing = set(REQUIRED_COLUMNS) - set(rows.columns)
    if missing:
        raise DataError(
            f"{path}: not a slipbench results file (missing columns: {', '.join(sorted(missing))})"
        )
    rows.attrs["unproven"] = unproven
    rows.attrs["unproven_keys"] = keys
    return rows


def results_folder(path: str | os.PathLike) -> Path:
    """The results folder of ``path``: the folder itself, or the one holding a results file."""
    path = Path(path)
    return path if path.is_dir() else path.parent


PREDICTION_COLUMNS = ("recording_id", "window_index", "y_true", "score")


def read_predictions(folder: Path, key: str) -> pd.DataFrame | None:
    """The stored test predictions of cell ``key`` (with ``trial`` where stored), or None where
    the folder holds none; a file that cannot be read is a DataError naming it."""
    path = folder / "predictions" / f"{key}.parquet"
    if not path.is_file():
        return None
    try:
        pf = open_parquet(path)
        names = set(pf.schema_arrow.names)
        if missing := [c for c in PREDICTION_COLUMNS if c not in names]:
            raise DataError(
                f"{path}: not a readable predictions file (it lacks the columns {', '.join(missing)})"
            )
        columns = [*PREDICTION_COLUMNS, *(["trial"] if "trial" in names else [])]
        return whole_text(pf.read(columns=columns), path).to_pandas()
    except (OSError, pa.ArrowException) as exc:
        raise read_error(exc, path, "not a readable predictions file") from None


def check_unique_keys(rows: pd.DataFrame, source: str) -> pd.DataFrame:
    """Refuse rows whose ``key`` repeats: the same results given twice (``report A A``) would
    count as two seeds, or pair a cell with itself.

    Raises
    ------
    DataError
        Naming how many keys repeat, in how many rows, and the first of them.
    """
    counts = rows["key"].value_counts()
    dup = counts[counts > 1]
    if len(dup):
        raise DataError(
            f"{source}: {len(dup)} key{'s' * (len(dup) > 1)} appear more than once ({int(dup.sum())} rows; "
            f"key {dup.index[0]} {int(dup.iloc[0])} times): the same results were given twice; give each "
            "results file or folder once"
        )
    return rows


def cells_failed(rows: pd.DataFrame, where: str = "") -> CellsFailed | None:
    """The CellsFailed error (exit 4) for rows whose status is neither ok nor skipped, or None.

    Each cell is labelled by protocol, detector and its cell key, e.g.
    ``window-size/holweg {"sensor": "nano17", "window": 50}``.
    """
    bad = rows[~rows["status"].isin(["ok", "skipped"])]
    if bad.empty:
        return None
    cell = bad["cell"] if "cell" in bad else pd.Series("", index=bad.index)
    reason = bad["reason"] if "reason" in bad else pd.Series("", index=bad.index)
    cells: Sequence[tuple[str, str, str]] = [
        (f"{p}/{d} {c}".rstrip(), str(s), "" if r is None or r != r else str(r))
        for p, d, c, s, r in zip(
            bad["protocol"], bad["detector"], cell.fillna(""), bad["status"], reason
        )
    ]
    return CellsFailed(cells, total=len(rows), where=where)
