"""The history: result rows of many runs, one run per commit, append-only, as a partitioned
Parquet dataset (``docs/guides/history.md`` documents the format)::

    HISTORY/
      runs/month=YYYY-MM/<commit>.parquet   one run's rows, written once, atomically; the
                                            source of truth (Hive-partitioned by the month of
                                            the run's date, so pyarrow.dataset reads it as is)
      index.parquet                         every run's rows in one file: a cache that each
                                            ``history add`` rebuilds; a reader takes from the
                                            run files what it lacks or holds otherwise
      .lock                                 held while the index is rebuilt

A run is added once: a commit the history holds already is not added again (the history does
not change), whatever its rows. A run's rows are a results folder's verified rows (read through
:func:`slipbench.store.results.read_results`) with the run's commit, date, machine and bench file
digest on each, the columns of :data:`COLUMNS` and nothing else, and in the file's metadata a
digest of its values (:func:`table_digest`), checked when a run file is read.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import pandas as pd
import pyarrow as pa

from slipbench.atomic import check_writable, folder_lock, make_folder, open_parquet, write_atomic
from slipbench.errors import DataError, UsageError, environment_fault
from slipbench.store.columns import names

FORMAT_VERSION = 1
INDEX_FILE = "index.parquet"
RUNS = "runs"
_META = b"slipbench.history"
#: a commit names its run's file: letters, digits, '.', '_' and '-', as git, hg and tags spell them
COMMIT = re.compile(r"[0-9A-Za-z][0-9A-Za-z._-]{0,99}")
#: the run's columns, on each of its rows
RUN_COLUMNS = ("commit", "date", "machine", "bench_digest")
#: the figures a history keeps (the gate's), each with its standard error and 95 % bounds
FIGURES = names(gated=True)
#: every column of a history row and its type (docs/guides/history.md says what each means)
COLUMNS: dict[str, pa.DataType] = {
    **dict.fromkeys(RUN_COLUMNS, pa.string()),
    "series": pa.string(),
    "series_label": pa.string(),
    "key": pa.string(),
    "row_digest": pa.string(),
    "code_identity": pa.string(),
    "protocol": pa.string(),
    "protocol_params": pa.string(),
    "detector": pa.string(),
    "detector_id": pa.string(),
    "detector_params": pa.string(),
    "split": pa.string(),
    "labels": pa.string(),
    "input": pa.string(),
    "normalize": pa.string(),
    "cell": pa.string(),
    "dataset_fingerprint": pa.string(),
    "seed": pa.int64(),
    "status": pa.string(),
    "low_n": pa.bool_(),
    "df": pa.float64(),
    "n_test_trials": pa.int64(),
    **{f"{f}{end}": pa.float64() for f in FIGURES for end in ("", "_se", "_lo", "_hi")},
}
SCHEMA = pa.schema(list(COLUMNS.items()))


@dataclass(frozen=True)
class Run:
    """What a run is added with: its commit, date (ISO 8601, UTC), machine and the SHA-256 of
    the bench file it ran ("" where it ran none)."""

    commit: str
    date: str
    machine: str
    bench_digest: str = ""


def utc_date(text: str | None) -> str:
    """``text`` (ISO 8601; None: now) as ``YYYY-MM-DDTHH:MM:SSZ`` in UTC; a date without a zone
    is taken as UTC. A UsageError names a text that is not a date."""
    if text is None:
        when = datetime.now(timezone.utc)
    else:
        try:
            when = datetime.fromisoformat(text.strip().replace("Z", "+00:00"))
        except ValueError:
            raise UsageError(
                f"--date: {text!r} is not an ISO 8601 date (2026-05-01T12:00:00Z)"
            ) from None
    if when.tzinfo is None:
        when = when.replace(tzinfo=timezone.utc)
    return when.astimezone(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


def check_commit(commit: str) -> str:
    """``commit`` where it can name a file; a UsageError otherwise."""
    if not COMMIT.fullmatch(commit):
        raise UsageError(
            f"--commit: {commit!r} is not a commit id (letters, digits, '.', '_' and '-', "
            "at most 100, starting with a letter or digit)"
        )
    return commit


def run_path(history: Path, run: Run) -> Path:
    return history / RUNS / f"month={run.date[:7]}" / f"{run.commit}.parquet"


def held(history: Path, commit: str) -> Path | None:
    """The run file of ``commit`` where the history holds it."""
    found = sorted((history / RUNS).glob(f"month=*/{commit}.parquet"))
    return found[0] if found else None


def run_table(rows: pd.DataFrame, run: Run) -> pa.Table:
    """A run's rows as its file holds them: the run's columns on each row, every column of
    :data:`COLUMNS` (missing ones empty), their digests in the metadata."""
    frame = rows.assign(**{c: getattr(run, c) for c in RUN_COLUMNS})
    frame = frame.assign(**{c: None for c in COLUMNS if c not in frame})[list(COLUMNS)]
    frame = frame.astype(object).where(frame.notna(), None)
    table = pa.Table.from_pylist(frame.to_dict("records"), schema=SCHEMA)
    meta = {"format": FORMAT_VERSION, "commit": run.commit, "rows": len(frame)}
    meta["digest"] = table_digest(table)
    return table.replace_schema_metadata({_META: json.dumps(meta)})


def table_digest(table: pa.Table) -> str:
    """A digest of a history table's values, whatever its layout in memory or on disk: each
    row hashed by pandas (vectorized: a run's 300 rows in a millisecond, where a digest per row
    in Python took a second per thousand runs), the hashes hashed."""
    hashes = pd.util.hash_pandas_object(table.to_pandas(), index=False).to_numpy()
    return hashlib.sha256(hashes.tobytes()).hexdigest()[:16]


def add_run(history: str | os.PathLike, rows: pd.DataFrame, run: Run) -> Path | None:
    """Add one run's rows (with their ``series``, :func:`slipbench.stats.series.series_rows`)
    and rebuild the index; None, with nothing written, where the history holds the commit."""
    history = Path(history)
    check_commit(run.commit)
    if held(history, run.commit) is not None:
        return None
    check_writable(history)
    path = run_path(history, run)
    with folder_lock(make_folder(history)):
        if held(history, run.commit) is not None:  # added meanwhile by another process
            return None
        write_atomic(run_table(rows, run), path)
        _rebuild_index(history)
    return path


def _run_files(history: Path) -> dict[str, Path]:
    """Every run file by its path under the history, in a stable order."""
    try:
        found = sorted((history / RUNS).glob("month=*/*.parquet"))
    except OSError as exc:
        raise environment_fault(exc, history / RUNS, "read") from None
    return {p.relative_to(history).as_posix(): p for p in found if not p.name.startswith(".")}


def _read_run(path: Path) -> pa.Table:
    """A run file's rows, checked against the digests it was written with."""
    try:
        table = open_parquet(path).read()
    except (OSError, pa.ArrowException) as exc:
        raise DataError(f"{path}: not a readable history run ({exc})") from None
    try:
        meta = json.loads((table.schema.metadata or {}).get(_META, b""))
        written = meta["digest"]
    except (ValueError, KeyError, TypeError):
        raise DataError(f"{path}: not a slipbench history run (no digest)") from None
    missing = [c for c in COLUMNS if c not in table.column_names]
    if missing:
        raise DataError(f"{path}: a history run lacks the columns {', '.join(missing)}")
    table = table.select(list(COLUMNS)).cast(SCHEMA).replace_schema_metadata(None)
    if table_digest(table) != written:
        raise DataError(
            f"{path}: its rows are not what was written ({table.num_rows} rows now, "
            f"{meta.get('rows')} written; edited or truncated); restore the file from where "
            "the history is kept"
        )
    return table


def _read_index(history: Path) -> tuple[pa.Table | None, dict[str, int]]:
    """The index and the size of each run file it holds; (None, {}) where there is none."""
    path = history / INDEX_FILE
    if not path.is_file():
        return None, {}
    try:
        table = open_parquet(path).read()
        manifest = json.loads((table.schema.metadata or {}).get(_META, b"{}"))["files"]
    except (OSError, pa.ArrowException, ValueError, KeyError, TypeError):
        return None, {}  # a cache: read the runs instead, and the next add rebuilds it
    if [c for c in COLUMNS if c not in table.column_names]:
        return None, {}
    return table.select(list(COLUMNS)).cast(SCHEMA), manifest


def _tables(
    history: Path,
) -> tuple[pa.Table | None, dict[str, int], list[pa.Table], dict[str, int]]:
    """The index's rows of the run files it holds as they are, and the other run files'."""
    files = _run_files(history)
    index, manifest = _read_index(history)
    sizes = {name: p.stat().st_size for name, p in files.items()}
    stale = [n for n in manifest if sizes.get(n) != manifest[n]]
    if index is not None and stale:  # a run file removed or rewritten: the index says otherwise
        index, manifest = None, {}
    fresh = [_read_run(p) for n, p in files.items() if n not in manifest]
    return index, manifest, fresh, sizes


def _rebuild_index(history: Path) -> None:
    index, manifest, fresh, sizes = _tables(history)
    if not fresh and index is not None:
        return
    table = pa.concat_tables([t for t in (index, *fresh) if t is not None])
    meta = {"format": FORMAT_VERSION, "files": sizes}
    write_atomic(table.replace_schema_metadata({_META: json.dumps(meta)}), history / INDEX_FILE)


def read_history(history: str | os.PathLike, columns: list[str] | None = None) -> pd.DataFrame:
    """Every row of a history, with ``run``: its run's position, oldest first (by date, then
    commit). ``columns``: only these (and the run's), for speed.

    Raises
    ------
    DataError
        No history here, or a run file that is not what was written.
    """
    history = Path(history)
    if not (history / RUNS).is_dir():
        raise DataError(f"{history}: no history here (add a run with `slipbench history add`)")
    index, _, fresh, _ = _tables(history)
    parts = [t for t in (index, *fresh) if t is not None]
    if not parts:
        raise DataError(f"{history}: the history holds no run")
    table = pa.concat_tables(parts)
    if columns is not None:
        keep = list(dict.fromkeys([*RUN_COLUMNS, *columns]))
        table = table.select([c for c in keep if c in COLUMNS])
    frame = table.to_pandas()
    order = frame[["date", "commit"]].drop_duplicates().sort_values(["date", "commit"])
    position = {c: i for i, c in enumerate(order["commit"])}
    frame["run"] = frame["commit"].map(position).astype(int)
    return frame
