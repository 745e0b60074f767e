"""The history: result rows of many runs, one run per commit, append-only, as a partitioned
Parquet dataset (``docs/guides/history.md`` documents the format)::

    HISTORY/
      runs/month=YYYY-MM/<commit>.parquet   one run's rows, written once, atomically; the
                                            source of truth (Hive-partitioned by the month of
                                            the run's date, so pyarrow.dataset reads it as is)
      index.parquet                         every run's rows in one file: a cache that each
                                            ``history add`` rebuilds
      .lock                                 held while the index is rebuilt

A run is added once: a commit the history holds already is not added again (the history does
not change), whatever its rows. A run's rows are a results folder's verified rows (read through
:func:`slipbench.store.results.read_results`) with the run's commit, date, machine and bench file
digest on each, the columns of :data:`COLUMNS` and nothing else; ``proven`` says whether the
result row proved itself by its digest when it was added.

Whatever is read back proves itself (:mod:`slipbench.store.digests`):

- a run file carries each row's digest and, in ``slipbench.history``, its commit, date, row
  count and a digest of its row digests; one that fails them, or whose name or month is not its
  run's, or whose commit another file holds, is refused by name (a DataError, exit 2);
- the index carries a digest of each column and a manifest (each run file's path, size, rows
  and digest, in the order of its rows), both under one digest; a reader checks what it reads.
  An index that is missing, damaged, edited, or that disagrees with the run files (one gone, or
  of another size) is rebuilt from the run files with one ``warning:`` line; run files it does
  not hold are read and proved.

Checking every run file on every read would cost a long history minutes (10,000 files), so a
run file the proved index holds at its recorded size is not read: damage inside it changes
nothing a reader shows, and is refused by name when the index is next rebuilt from the files.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import warnings
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc

from slipbench.atomic import (
    check_writable,
    folder_lock,
    make_folder,
    open_parquet,
    whole_text,
    write_atomic,
)
from slipbench.errors import DataError, EnvironmentFault, UsageError, environment_fault
from slipbench.store.columns import names
from slipbench.store.digests import (
    column_digest,
    digests_of,
    failing,
    with_digests,
    written_digests,
)
from slipbench.store.scan import read_error, rows_of, whole

FORMAT_VERSION = 2
INDEX_FILE = "index.parquet"
RUNS = "runs"
_META = "slipbench.history"
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
    "proven": pa.bool_(),
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
#: what to do with a run file that cannot be read as written
RESTORE = "restore it from where the history is kept, or move it out of runs/ to drop its run"


@dataclass(frozen=True)
class Run:
    """What a run is added with: its commit, date (ISO 8601, UTC), machine and the SHA-256 of
    the bench file it ran ("" where it ran none)."""

    commit: str
    date: str
    machine: str
    bench_digest: str = ""


def utc_date(text: str | None, option: str = "--date") -> str:
    """``text`` (ISO 8601; None: now) as ``YYYY-MM-DDTHH:MM:SSZ`` in UTC, the year in four
    digits (so that dates sort as text); a date without a zone is taken as UTC. A UsageError
    names a text that is not a date, or one whose UTC time falls outside years 1 to 9999."""
    if text is None:
        when = datetime.now(timezone.utc)
    else:
        try:
            when = datetime.fromisoformat(text.strip().replace("Z", "+00:00"))
        except ValueError:
            raise UsageError(
                f"{option}: {text!r} is not an ISO 8601 date (2026-05-01T12:00:00Z)"
            ) from None
    if when.tzinfo is None:
        when = when.replace(tzinfo=timezone.utc)
    try:
        when = when.astimezone(timezone.utc)
    except OverflowError:
        raise UsageError(
            f"{option}: {text!r} falls outside years 1 to 9999 once made UTC"
        ) from None
    # strftime's %Y writes year 999 as "999", which sorts after "2026"
    return f"{when.year:04d}-{when:%m-%dT%H:%M:%SZ}"


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


def _json_digest(value: Any) -> str:
    text = json.dumps(value, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def run_table(rows: pd.DataFrame, run: Run) -> pa.Table:
    """A run's rows as its file holds them: the run's columns on each row, every column of
    :data:`COLUMNS` (missing ones empty; ``proven`` must be said), each row's digest and the
    run's own in the metadata."""
    if "proven" not in rows or rows["proven"].isna().any():
        raise ValueError("a run's rows must say whether each proved itself (proven)")
    frame = rows.assign(**{c: getattr(run, c) for c in RUN_COLUMNS})
    frame = frame.assign(**{c: None for c in COLUMNS if c not in frame})[list(COLUMNS)]
    frame = frame.astype(object).where(frame.notna(), None)
    table = pa.Table.from_pylist(frame.to_dict("records"), schema=SCHEMA)
    digests = digests_of(table.to_pylist())
    if len(digests) != table.num_rows:
        raise ValueError(f"the run of {run.commit} holds a key twice")
    meta = {
        "format": FORMAT_VERSION,
        "commit": run.commit,
        "date": run.date,
        "rows": table.num_rows,
        "digest": _json_digest(digests),
    }
    return with_digests(table, digests, **{_META: json.dumps(meta)})


def add_run(history: str | os.PathLike, rows: pd.DataFrame, run: Run) -> Path | None:
    """Add one run's rows (with their ``series``, :func:`slipbench.history.series.series_rows`,
    and ``proven``) and rebuild the index; None, with nothing written, where the history holds
    the commit."""
    history = Path(history)
    check_commit(run.commit)
    if history.exists() and not history.is_dir():
        raise UsageError(f"--history: {history} is a file, not a history folder")
    if held(history, run.commit) is not None:
        return None
    check_writable(history)
    path = run_path(history, run)
    with folder_lock(make_folder(history)):
        if held(history, run.commit) is not None:  # added meanwhile by another process
            return None
        write_atomic(run_table(rows, run), path)
        files = _run_files(history)
        table, entries = _current(history, files, list(COLUMNS), path.relative_to(history))
        _write_index(history, table, entries)
    return path


@dataclass(frozen=True)
class RunFile:
    """A run file's rows, proved, and its entry in the index's manifest."""

    path: Path
    commit: str
    table: pa.Table
    entry: dict[str, Any]  # size, rows, digest


def _run_files(history: Path) -> dict[str, tuple[Path, int]]:
    """Every run file (its path and size) by its path under the history, in a stable order."""
    try:
        found = sorted((history / RUNS).glob("month=*/*.parquet"))
        return {
            p.relative_to(history).as_posix(): (p, p.stat().st_size)
            for p in found
            if not p.name.startswith(".")
        }
    except OSError as exc:
        raise environment_fault(exc, history / RUNS, "read") from None


def _read_run(path: Path, size: int) -> RunFile:
    """A run file's rows, proved by the digests it was written with and by its name and
    folder (a copy under another name or month is refused)."""
    try:
        data, _ = whole(path)
        table = open_parquet(data, path).read()
    except (OSError, pa.ArrowException) as exc:
        raise read_error(exc, path, "not a readable history run file") from None
    table = whole_text(table, path, key="key")
    meta = _run_meta(table, path)
    digests = written_digests(table, path)
    if digests is None:
        raise DataError(f"{path}: not a slipbench history run file (it carries no row digests)")
    for name, kind in COLUMNS.items():
        if name not in table.column_names:
            raise DataError(f"{path}: a history run file lacks the column {name!r}; {RESTORE}")
        if table.schema.field(name).type != kind:
            found = table.schema.field(name).type
            raise DataError(f"{path}: column {name!r} holds {found}, not {kind}; {RESTORE}")
    table = table.select(list(COLUMNS)).replace_schema_metadata(None)
    rows = rows_of(table, path)
    bad = failing(rows, digests)
    if bad or len(digests) != len(rows) or meta["rows"] != len(rows):
        raise DataError(
            f"{path}: its rows are not what was written ({len(bad)} of {len(rows)} rows fail "
            f"their digest, {meta['rows']} rows written: the file is damaged or was edited); "
            + RESTORE
        )
    if _json_digest(digests) != meta["digest"]:
        raise DataError(f"{path}: its row digests are not those it was written with; {RESTORE}")
    _check_place(path, meta, table)
    return RunFile(
        path, meta["commit"], table, {"size": size, **{k: meta[k] for k in ("rows", "digest")}}
    )


def _run_meta(table: pa.Table, path: Path) -> dict[str, Any]:
    """A run file's ``slipbench.history`` entry: its format, commit, date, rows and digest."""
    text = (table.schema.metadata or {}).get(_META.encode())
    try:
        meta = json.loads(text) if text is not None else None
    except ValueError:  # UnicodeDecodeError too
        meta = None
    kinds = {"format": int, "commit": str, "date": str, "rows": int, "digest": str}
    if isinstance(meta, dict) and isinstance(meta.get("format"), int):
        if meta["format"] != FORMAT_VERSION:
            raise DataError(
                f"{path}: a history run file of format {meta['format']}; this slipbench reads "
                f"format {FORMAT_VERSION} (add the run again with this version)"
            )
        if all(isinstance(meta.get(k), t) for k, t in kinds.items()):
            return meta
    raise DataError(
        f"{path}: not a slipbench history run file (its {_META} metadata is missing or "
        f"damaged); {RESTORE}"
    )


def _check_place(path: Path, meta: dict[str, Any], table: pa.Table) -> None:
    """Refuse a run file held under another run's name or month: it would be read twice."""
    commits = pc.unique(table["commit"]).to_pylist()
    dates = pc.unique(table["date"]).to_pylist()
    if commits != [meta["commit"]] or dates != [meta["date"]]:
        raise DataError(f"{path}: its rows are not all of the run it records; {RESTORE}")
    if path.name != f"{meta['commit']}.parquet":
        raise DataError(
            f"{path}: it holds the run of commit {meta['commit']!r}, not the one its name says "
            "(a copy of another run's file?); move it out of runs/"
        )
    if path.parent.name != f"month={meta['date'][:7]}":
        raise DataError(
            f"{path}: its run's date is {meta['date']}, so it belongs in "
            f"month={meta['date'][:7]}, not {path.parent.name} (a copy?); move it out of runs/"
        )


def _once(held_by: dict[str, str], runs: list[RunFile]) -> None:
    """Refuse a commit held by two run files, naming both (``held_by``: commit -> file)."""
    for run in runs:
        other = held_by.setdefault(run.commit, str(run.path))
        if other != str(run.path):
            raise DataError(
                f"{run.path}: commit {run.commit!r} is held by {other} too (one run in two files: "
                "a copy?); move one of them out of runs/"
            )


def _index_problem(meta: Any) -> str:
    """What is wrong with an index's ``slipbench.history`` metadata ("" where nothing is)."""
    if not isinstance(meta, dict) or meta.get("format") != FORMAT_VERSION:
        return "is not of this slipbench's format"
    files, columns = meta.get("files"), meta.get("columns")
    entry = {"size": int, "rows": int, "digest": str}
    if not (
        isinstance(files, dict)
        and all(
            isinstance(e, dict) and all(isinstance(e.get(k), t) for k, t in entry.items())
            for e in files.values()
        )
        and isinstance(columns, dict)
        and all(isinstance(columns.get(c), str) for c in COLUMNS)
    ):
        return "has a damaged manifest"
    if meta.get("digest") != _json_digest({k: v for k, v in meta.items() if k != "digest"}):
        return "has a manifest that is not the one it was written with"
    return ""


def _open_index(path: Path, coded: list[str]) -> tuple[Any, dict[str, Any], str]:
    """The index's Parquet file (``coded``: columns read as dictionaries) and its checked
    metadata, or why it cannot be used."""
    if not path.is_file():
        return None, {}, "is missing"
    try:
        pf = open_parquet(path, read_dictionary=coded)
        meta = json.loads((pf.schema_arrow.metadata or {})[_META.encode()])
    except KeyError:
        return None, {}, "carries no manifest"
    except (DataError, OSError, pa.ArrowException, ValueError) as exc:  # UnicodeDecodeError too
        return None, {}, f"is damaged ({' '.join(str(exc).split())[:200]})"
    problem = _index_problem(meta)
    kinds = [(f.name, _plain_type(f.type)) for f in pf.schema_arrow]
    if not problem and kinds != list(COLUMNS.items()):
        problem = "has columns of other names or types than a history's"
    return pf, meta, problem


def _plain_type(kind: pa.DataType) -> pa.DataType:
    """A column's type, a dictionary's its values' (as the file holds them)."""
    return kind.value_type if pa.types.is_dictionary(kind) else kind


def _read_index(
    history: Path, sizes: dict[str, int], needed: list[str], coded: list[str] | None = None
) -> tuple[pa.Table | None, dict[str, dict[str, Any]], str]:
    """The index's ``needed`` columns, each proved by its digest, and its manifest; or why it
    cannot be used (missing, damaged, edited, or disagreeing with the run files). ``coded``:
    text columns read as Parquet keeps them, a dictionary of values and a code per row."""
    pf, meta, problem = _open_index(history / INDEX_FILE, coded or [])
    if problem:
        return None, {}, problem
    files: dict[str, dict[str, Any]] = meta["files"]
    changed = [n for n, e in files.items() if sizes.get(n) != e["size"]]
    if changed:
        return (
            None,
            {},
            (
                f"disagrees with the run files ({len(changed)} of them gone or of another size, "
                f"e.g. {changed[0]})"
            ),
        )
    try:
        table = pf.read(columns=needed)
    except (OSError, pa.ArrowException, ValueError) as exc:
        return None, {}, f"is damaged ({' '.join(str(exc).split())[:200]})"
    if table.num_rows != sum(e["rows"] for e in files.values()):
        return None, {}, "holds other rows than its manifest says"
    for name in needed:
        if column_digest(table[name]) != meta["columns"][name]:
            return None, {}, f"holds values of {name!r} that are not those it was written with"
    if _runs_in(table["commit"]) != [(Path(n).stem, e["rows"]) for n, e in files.items()]:
        return None, {}, "holds other runs than its manifest says"
    return table.replace_schema_metadata(None), files, ""


def _stretches(column: pa.ChunkedArray) -> tuple[np.ndarray, list]:
    """Where each stretch of one value of a column starts (and, last, the column's length),
    and each stretch's value; a dictionary column compared by its codes."""
    n = len(column)
    if n == 0:
        return np.zeros(1, np.int64), []
    if pa.types.is_dictionary(column.type):
        column = column.unify_dictionaries()
        codes = np.concatenate([c.indices.to_numpy(zero_copy_only=False) for c in column.chunks])
        changed = codes[1:] != codes[:-1]
    else:
        changed = pc.not_equal(column[1:], column[:-1]).to_numpy(zero_copy_only=False)
    edges = np.concatenate([[0], np.flatnonzero(changed) + 1, [n]])
    return edges, column.take(pa.array(edges[:-1])).to_pylist()


def _runs_in(commits: pa.ChunkedArray) -> list[tuple[str, int]]:
    """Each stretch of one commit in a column, with its length, in order."""
    edges, values = _stretches(commits)
    return list(zip(values, np.diff(edges).tolist()))


def _current(
    history: Path,
    files: dict[str, tuple[Path, int]],
    needed: list[str],
    new: Path | None = None,
    read: tuple[pa.Table | None, dict[str, dict[str, Any]], str] | None = None,
) -> tuple[pa.Table, dict[str, dict[str, Any]]]:
    """The history's rows (``needed`` columns) and the manifest they match: the index's, proved,
    and the run files it does not hold, each read and proved; every run file read where the
    index cannot be used, saying so in one line (not for a first index, nor where ``new``, the
    run just written, is the only file it lacks); ``read``: the index as already read."""
    sizes = {n: s for n, (_, s) in files.items()}
    index, manifest, problem = read or _read_index(history, sizes, needed)
    if problem:
        runs = [_read_run(p, s) for p, s in files.values()]
        _once({}, runs)
        if set(files) - {new.as_posix() if new else ""}:
            warnings.warn(
                f"{history / INDEX_FILE} {problem}: rebuilt from the {len(runs)} run files",
                stacklevel=3,
            )
        tables: list[pa.Table] = []
        manifest = {}
    else:
        runs = [_read_run(p, s) for n, (p, s) in files.items() if n not in manifest]
        _once({Path(n).stem: n for n in manifest}, runs)
        tables = [index] if index is not None else []
        manifest = dict(manifest)
    for run in runs:
        # as the index's columns came (a text column as a dictionary, where read so)
        table = run.table.select(needed)
        tables.append(table.cast(tables[0].schema) if tables else table)
        manifest[run.path.relative_to(history).as_posix()] = run.entry
    schema = pa.schema([(c, COLUMNS[c]) for c in needed])
    return pa.concat_tables(tables) if tables else schema.empty_table(), manifest


def _write_index(history: Path, table: pa.Table, manifest: dict[str, dict[str, Any]]) -> None:
    meta: dict[str, Any] = {
        "format": FORMAT_VERSION,
        "files": manifest,
        "columns": {c: column_digest(table[c]) for c in COLUMNS},
    }
    meta["digest"] = _json_digest(meta)
    write_atomic(table.replace_schema_metadata({_META: json.dumps(meta)}), history / INDEX_FILE)


def _rows(history: Path, needed: list[str], coded: list[str]) -> pa.Table:
    """The history's rows (``coded``: those text columns as dictionaries where the index is
    read); where the index had to be rebuilt, it is written again where this process may
    (under the history's lock), so that the next read is fast."""
    files = _run_files(history)
    read = _read_index(history, {n: s for n, (_, s) in files.items()}, needed, coded)
    if not read[2] or not files:
        return _current(history, files, needed, read=read)[0]
    try:
        with folder_lock(history):
            files = _run_files(history)
            table, manifest = _current(history, files, list(COLUMNS))
            _write_index(history, table, manifest)
    except EnvironmentFault:  # a history this process may read, not write
        table, _ = _current(history, files, list(COLUMNS))
    return table.select(needed)


def read_history(
    history: str | os.PathLike, columns: list[str] | None = None, categorical: bool = False
) -> pd.DataFrame:
    """Every row of a history, with ``run``: its run's position, oldest first (by date, then
    commit). ``columns``: only these (and the run's), for speed. ``categorical``: text columns
    (but ``key``, one per row) as pandas categoricals, read as Parquet keeps them (a value
    once, a code per row), so that their memory grows with the values, not the rows.

    Raises
    ------
    DataError
        No history here, or a run file that is not what was written, or two run files of one
        commit (each named).
    """
    history = Path(history)
    if not (history / RUNS).is_dir():
        raise DataError(f"{history}: no history here (add a run with `slipbench history add`)")
    needed = list(COLUMNS)
    if columns is not None:
        needed = [c for c in dict.fromkeys([*RUN_COLUMNS, *columns]) if c in COLUMNS]
    coded = [c for c in needed if categorical and c != "key" and COLUMNS[c] == pa.string()]
    table = _rows(history, needed, coded)
    if table.num_rows == 0:
        raise DataError(f"{history}: the history holds no run")
    run = _positions(table)
    if coded:  # where the index was rebuilt, its columns came as text
        table = pa.table(
            [
                pc.dictionary_encode(table[c])
                if c in coded and table[c].type == pa.string()
                else table[c]
                for c in table.column_names
            ],
            names=table.column_names,
        )
    # each column freed as it is converted: the table and the frame are not held whole at once
    frame = table.to_pandas(split_blocks=True, self_destruct=True)
    del table
    frame["run"] = run
    return frame


def _positions(table: pa.Table) -> np.ndarray:
    """Each row's run: its run's position among the runs sorted by date, then commit. A run's
    rows are one stretch (a run file's), so each stretch is ordered, not each row."""
    edges, commits = _stretches(table["commit"])
    dates = table["date"].take(pa.array(edges[:-1])).to_pylist()
    order = sorted(set(zip(dates, commits)))
    position = {c: i for i, (_, c) in enumerate(order)}
    return np.repeat([position[c] for c in commits], np.diff(edges)).astype(int)
