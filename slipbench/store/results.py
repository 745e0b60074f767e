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
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc

from slipbench.atomic import (
    RESULTS_CELLS,
    check_writable,
    folder_lock,
    make_folder,
    open_parquet,
    write_atomic,
    write_text_atomic,
)
from slipbench.errors import ENVIRONMENT_ERRNOS, CellsFailed, DataError, environment_fault
from slipbench.store.columns import checked
from slipbench.store.keys import canonical_json, cell_key

__all__ = [
    "RESULTS_FILE",
    "REQUIRED_COLUMNS",
    "ResultsStore",
    "read_results",
    "read_predictions",
    "results_folder",
    "cells_failed",
    "cell_key",
    "write_atomic",
    "write_text_atomic",
]

RESULTS_FILE = "results.parquet"
#: columns every results row has, whatever its status (metrics exist only for cells that ran)
REQUIRED_COLUMNS = ("key", "protocol", "detector", "status")
_MANIFEST = b"slipbench.cells"  # Parquet metadata of results.parquet: cell file versions it holds
_DIGESTS = b"slipbench.rows"  # and a digest of each row it holds (:func:`row_digest`)
MISMATCHES_NAMED = 3  # rows named in the message about a results file that does not match


def _version(st: os.stat_result) -> list[int]:
    # every atomic write makes a new inode, so a rewrite is seen even where mtime is coarse
    return [st.st_size, st.st_mtime_ns, st.st_ino]


@dataclass
class _Scan:
    """What a results folder holds: results.parquet's table, and the cell files it lacks."""

    table: pa.Table | None  # results.parquet, or None
    newer: dict[
        str, dict[str, Any]
    ]  # rows of cell files that results.parquet lacks or says otherwise
    versions: dict[str, list[int]]  # the version of each cell file whose row is known
    unreadable: list[tuple[Path, str]]  # cell files that could not be read, and why
    digests: dict[str, str] = field(default_factory=dict)  # results.parquet's, as it says

    @property
    def changed(self) -> bool:
        """Whether results.parquet must be rebuilt to hold every row."""
        return bool(self.newer)

    def _older(self) -> pa.Table | None:
        if self.table is None or not self.newer:
            return self.table
        return self.table.filter(
            pc.invert(pc.is_in(self.table["key"], pa.array(list(self.newer), pa.string())))
        )

    def rows(self) -> dict[str, dict[str, Any]]:
        older = self._older()
        rows = {} if older is None else {r["key"]: r for r in older.to_pylist()}
        return {**rows, **self.newer}

    def frame(self) -> pd.DataFrame:
        older = self._older()
        parts = ([] if older is None else [older.to_pandas()]) + (
            [pd.DataFrame(list(self.newer.values()))] if self.newer else []
        )
        return (
            pd.concat(parts, ignore_index=True)
            if len(parts) > 1
            else (parts[0] if parts else pd.DataFrame())
        )

    def row_digests(self) -> dict[str, str]:
        """Each row's :func:`row_digest`: results.parquet's own where it holds them for every
        row it keeps (no row is converted), the others computed."""
        older = self._older()
        out: dict[str, str] = {}
        if older is not None:
            keys = older["key"].to_pylist()
            if all(k in self.digests for k in keys):
                out = {k: self.digests[k] for k in keys}
            else:  # a file of an older slipbench
                out = {r["key"]: row_digest(r) for r in older.to_pylist()}
        return out | {k: row_digest(r) for k, r in self.newer.items()}

    def combined(self, folder: Path) -> pa.Table:
        """Every row as one table (protocols have different cell columns: the union is taken)."""
        older, newer = self._older(), _table(self.newer, folder)
        if older is None:
            return newer
        try:
            return pa.concat_tables([older, newer], promote_options="permissive")
        except (pa.ArrowInvalid, pa.ArrowTypeError):
            return _table(self.rows(), folder)  # names the column the rows disagree on


class ResultsStore:
    """A results folder (see the module's docstring for its layout and guarantees)."""

    def __init__(self, folder: str | os.PathLike):
        self.folder = Path(folder)

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
        """Every stored cell row by key: results.parquet, plus cells stored since it was written.

        One file read and one ``stat`` per cell for a consolidated folder. A cell file that
        cannot be read (damaged outside slipbench) is left out with a warning naming it, so that
        the run computes that cell again and replaces the file.
        """
        scan = self._scan()
        for path, why in scan.unreadable:
            warnings.warn(
                f"{path}: unreadable cell file, its cell will be computed again ({why})",
                stacklevel=2,
            )
        return scan.rows()

    def put(self, row: dict[str, Any], predictions: pd.DataFrame | None = None) -> None:
        """Store one finished cell (its columns those of :mod:`slipbench.store.columns`); its
        predictions first, so a row never lacks them."""
        checked(row)
        if predictions is not None:
            write_atomic(
                pa.Table.from_pandas(predictions, preserve_index=False),
                self.folder / "predictions" / f"{row['key']}.parquet",
            )
        write_atomic(pa.Table.from_pylist([row]), self._cell_path(row["key"]))

    def consolidate(self) -> Path:
        """Rebuild results.parquet from every finished cell, if any row changed; returns its path.

        A folder whose results.parquet is up to date is only read (no lock, no write). Otherwise
        the folder's lock is taken and the folder read again under it, so that a concurrent run's
        cells are never dropped.
        """
        path = self.folder / RESULTS_FILE
        unlocked = self._scan()
        if not unlocked.changed:
            return path
        with folder_lock(self.folder):
            scan = self._scan(known=unlocked)
            if scan.changed:
                table = scan.combined(self.folder)
                manifest, digests = (
                    json.dumps(d, separators=(",", ":"), sort_keys=True)
                    for d in (scan.versions, scan.row_digests())
                )
                metadata = {_MANIFEST: manifest, _DIGESTS: digests}
                write_atomic(table.replace_schema_metadata(metadata), path)
        return path

    def _scan(self, strict: bool = False, known: _Scan | None = None) -> _Scan:
        """results.parquet and every cell file whose version it does not hold. With ``strict``,
        an unreadable cell file is a DataError (a report must not silently miss a cell). Rows
        of ``known``, an earlier scan, are not read again where their file is unchanged."""
        path = self.folder / RESULTS_FILE
        cells = self.folder / RESULTS_CELLS
        try:
            entries = sorted(
                (
                    e
                    for e in os.scandir(cells)
                    if e.name.endswith(".parquet") and not e.name.startswith(".")
                ),
                key=lambda e: e.name,
            )  # a hidden .*.tmp file is a write that never finished
        except FileNotFoundError:
            entries = []
        except OSError as exc:
            raise environment_fault(exc, cells, "read") from None
        table, held, index = None, {}, {}
        if path.is_file():
            table = _read_table(path)
            if "key" not in table.column_names:
                raise DataError(f"{path}: not a slipbench results file (no key column)")
            if entries:  # rows are matched with cell files by key
                index = {k: i for i, k in enumerate(table["key"].to_pylist())}
                if len(index) < table.num_rows:
                    twice = pd.Series(table["key"].to_pylist()).value_counts()
                    raise DataError(
                        f"{path}: {int((twice > 1).sum())} key(s) appear more than once (e.g. {twice.index[0]}) "
                        "beside the cells/ folder; slipbench never writes that: delete the file and it is "
                        "rebuilt from cells/"
                    )
            try:
                held = json.loads((table.schema.metadata or {}).get(_MANIFEST, b"{}"))
            except ValueError:
                pass  # a results file from elsewhere: its rows are compared with the cells instead
        scan = _Scan(table, {}, {}, [], _written_digests(table))
        for entry in entries:
            key = entry.name[: -len(".parquet")]
            try:
                version = _version(entry.stat())
            except FileNotFoundError:
                continue  # removed since the listing
            if key in index and held.get(key) == version:
                scan.versions[key] = version
                continue
            if known is not None and key in known.newer and known.versions.get(key) == version:
                row = known.newer[key]
            else:
                try:
                    row, version = _read_cell(Path(entry.path), key)
                except DataError as exc:
                    if strict:
                        raise
                    scan.unreadable.append((Path(entry.path), str(exc).split(": ", 1)[-1]))
                    continue
            scan.versions[key] = version
            if (
                table is None  # then index is empty: mypy cannot tell
                or key not in index
                or not _same_row(row, table.slice(index[key], 1).to_pylist()[0])
            ):
                scan.newer[key] = row
        return scan


def _plain(value: Any) -> Any:
    """A row's value as :func:`~slipbench.store.keys.canonical` takes it (a value of another
    kind, which slipbench never writes, by its text)."""
    try:
        canonical_json({"v": value})
        return value
    except (TypeError, ValueError):
        return str(value)


def row_digest(row: dict[str, Any]) -> str:
    """A digest of what a result row says: its non-null values, canonical, so that the row as
    a cell file holds it and as results.parquet holds it (where a column of other protocols'
    cells is null, or an int column was promoted to float) digest alike."""
    plain = {str(k): _plain(v) for k, v in row.items() if v is not None}
    return hashlib.sha256(canonical_json(plain).encode()).hexdigest()[:16]


def _written_digests(table: pa.Table | None) -> dict[str, str]:
    """The row digests a results file was written with ({} where it holds none)."""
    text = ((table.schema.metadata or {}) if table is not None else {}).get(_DIGESTS)
    try:
        found = json.loads(text) if text else {}
    except ValueError:
        return {}
    return found if isinstance(found, dict) else {}


def _check_file(table: pa.Table, path: Path) -> None:
    """Refuse a results file whose rows are not those slipbench wrote (rows deleted, added or
    edited, columns swapped): by the row digests written in its metadata, else, beside a cells/
    folder, by the cell files; warn where cells/ holds cells the file lacks (a run since).
    A table written by other means, with neither, is read as it is.

    Raises
    ------
    DataError
        Naming what does not match: how many rows, and the first of them with their columns.
    """
    cells = path.parent / RESULTS_CELLS
    digests = _written_digests(table)
    if not digests and not cells.is_dir():
        return
    here = {str(r.get("key")): r for r in table.to_pylist()}
    if digests:
        changed = [k for k, r in here.items() if k in digests and digests[k] != row_digest(r)]
        lost, added = sorted(set(digests) - set(here)), sorted(set(here) - set(digests))
    else:  # written before rows had digests: its cell files are the reference
        changed = [k for k, r in here.items() if _cell_differs(cells, k, r)]
        lost, added = [], [k for k in here if not (cells / f"{k}.parquet").is_file()]
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
    stale = _stale_cells(table, cells, here)
    if stale:
        warnings.warn(
            f"{path}: {len(stale)} finished cell(s) of {cells} are not in this file as they are now "
            f"(e.g. {stale[0]}: a run since it was written, or one stopped before it was rebuilt); "
            "give the folder to read them",
            stacklevel=3,
        )


def _stale_cells(table: pa.Table, cells: Path, here: dict[str, dict[str, Any]]) -> list[str]:
    """The cells of ``cells`` a results file lacks, or holds otherwise than the cell file says
    now (read where its metadata records another version of the file: a copied folder's cells
    are read, not taken for changed)."""
    try:
        held = json.loads((table.schema.metadata or {}).get(_MANIFEST, b"{}"))
    except ValueError:
        held = {}
    out = []
    for key in _cell_keys(cells):
        if key not in here:
            out.append(key)
            continue
        try:
            version = _version((cells / f"{key}.parquet").stat())
        except FileNotFoundError:
            continue
        if held.get(key, version) != version and _cell_differs(cells, key, here[key]):
            out.append(key)
    return sorted(out)


def _cell_keys(cells: Path) -> list[str]:
    """The keys of the cell files in ``cells`` (none where there is no such folder)."""
    try:
        return [
            e.name[: -len(".parquet")]
            for e in os.scandir(cells)
            if e.name.endswith(".parquet") and not e.name.startswith(".")
        ]
    except FileNotFoundError:
        return []
    except OSError as exc:
        raise environment_fault(exc, cells, "read") from None


def _cell_differs(cells: Path, key: str, row: dict[str, Any]) -> bool:
    """Whether a results file's row says otherwise than its cell file (False where none is)."""
    if not (cells / f"{key}.parquet").is_file():
        return False
    try:
        cell, _ = _read_cell(cells / f"{key}.parquet", key)
    except DataError:
        return True
    return not _same_row(cell, row)


def _shown(value: Any) -> str:
    return f"{value:.6g}" if isinstance(value, float) else repr(value)


def _cell_says(cells: Path, key: str, row: dict[str, Any]) -> str:
    """How a results file's row differs from its cell file (the columns, with both values), or
    that it differs from what was written, where no readable cell file says more."""
    try:
        cell, _ = _read_cell(cells / f"{key}.parquet", key)
    except DataError:
        return "its content is not what was written"
    columns = sorted(
        {k for k, v in cell.items() if not _same(v, row.get(k))}
        | {k for k, v in row.items() if k not in cell and v is not None}
    )
    shown = ", ".join(
        f"{c} {_shown(row.get(c))} here, {_shown(cell.get(c))} in cells/" for c in columns[:4]
    )
    return shown + (f" and {len(columns) - 4} more columns" if len(columns) > 4 else "")


def _read_table(path: Path) -> pa.Table:
    try:
        return open_parquet(_whole(path)[0], path).read()
    except (OSError, pa.ArrowException) as exc:
        raise _read_error(exc, path, "not a readable results file") from None


def _whole(path: Path) -> tuple[pa.BufferReader, list[int]]:
    """A file's bytes and its version, from one open file.

    pyarrow given a path may open the file again for the data pages, and a concurrent
    consolidate may replace it in between (the footer of one file, the pages of another).
    Given a Python file object, it leaves work behind that can abort the interpreter at exit
    (apache/arrow#34314, #50482). In-memory bytes avoid both; results files are small.
    """
    with open(path, "rb") as fh:
        version = _version(os.fstat(fh.fileno()))
        return pa.BufferReader(fh.read()), version


def _read_error(exc: Exception, path: Path, what: str) -> Exception:
    """A permission or disk problem is the machine's (exit 5); anything else is the file's (exit 2)."""
    if isinstance(exc, OSError) and exc.errno in ENVIRONMENT_ERRNOS:
        return environment_fault(exc, path, "read")
    return DataError(f"{path}: {what} ({exc})")


def _read_cell(path: Path, key: str) -> tuple[dict[str, Any], list[int]]:
    """One cell's row and the version of the file it came from (both of one open file)."""
    try:
        data, version = _whole(path)
        rows = open_parquet(data, path).read().to_pylist()  # half read_table's cost for one row
    except (OSError, pa.ArrowException) as exc:
        raise _read_error(exc, path, "not a readable cell file") from None
    if len(rows) != 1 or rows[0].get("key") != key:
        raise DataError(
            f"{path}: a cell file holds one row whose key is its name, found "
            f"{len(rows)} row(s){'' if not rows else ' with key ' + repr(rows[0].get('key'))}"
        )
    return rows[0], version


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a == b


def _same_row(cell: dict[str, Any], stored: dict[str, Any]) -> bool:
    """Whether results.parquet's row says what the cell file says. Its other columns (of other
    protocols' cells) must be empty; ints it promoted to floats compare equal."""
    return all(_same(v, stored.get(k)) for k, v in cell.items()) and all(
        v is None for k, v in stored.items() if k not in cell
    )


def _table(rows: dict[str, dict[str, Any]], folder: Path) -> pa.Table:
    """One table of rows whose columns differ (each protocol has its own cell columns)."""
    if not rows:
        return pa.table({})
    try:
        return pa.Table.from_struct_array(pa.array(list(rows.values())))
    except (pa.ArrowInvalid, pa.ArrowTypeError):
        pass
    columns = dict.fromkeys(c for row in rows.values() for c in row)
    for column in columns:
        try:
            pa.array([row.get(column) for row in rows.values()])
        except (pa.ArrowInvalid, pa.ArrowTypeError) as exc:
            kinds = sorted(
                {type(r[column]).__name__ for r in rows.values() if r.get(column) is not None}
            )
            raise DataError(
                f"{folder}: cells disagree on the type of column {column!r} ({', '.join(kinds)}): "
                f"{exc}; rerun the cells of one of the plugins with --force"
            ) from None
    raise DataError(f"{folder}: the cell rows cannot be combined into one table")


def read_results(path: str | os.PathLike) -> pd.DataFrame:
    """Rows of a results file, or of every finished cell of a results folder.

    A folder is read as :meth:`ResultsStore.finished` reads it, so the cells of a run that was
    killed before rebuilding results.parquet are there; an unreadable cell file is a DataError
    naming it. Raises DataError when there is nothing to read or a required column is missing.
    """
    path = Path(path)
    if path.is_dir():
        rows = ResultsStore(path)._scan(strict=True).frame()
        if rows.empty:
            raise DataError(
                f"{path}: no results here (run `slipbench evaluate --out FOLDER` first)"
            )
    elif path.is_file():
        table = _read_table(path)
        _check_file(table, path)
        rows = table.to_pandas()
    else:
        raise DataError(
            f"{path}: no results file here (run `slipbench evaluate --out FOLDER` first)"
        )
    missing = set(REQUIRED_COLUMNS) - set(rows.columns)
    if missing:
        raise DataError(
            f"{path}: not a slipbench results file (missing columns: {', '.join(sorted(missing))})"
        )
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
        return pf.read(columns=columns).to_pandas()
    except (OSError, pa.ArrowException) as exc:
        raise _read_error(exc, path, "not a readable predictions file") from None


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
