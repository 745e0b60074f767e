"""Reading a results folder: ``results.parquet`` and the cell files it does not hold, each row
proved by its digest (:mod:`slipbench.store.digests`) before it is used or copied.

What a scan does with what it finds (``strict``: a report, which must not miss a cell; else a
run, which computes again what it cannot trust):

- a cell file that fails its digest, or cannot be read: a report refuses it by name; a run
  leaves its cell out (computed again when planned), with a line;
- ``results.parquet`` whose table digest matches: its rows are used as they are, unconverted
  until a row is asked for; otherwise each of its rows is checked against its own digest;
- a row of ``results.parquet`` that fails its digest: its cell file is read instead; without
  one, a report refuses the folder and a run leaves the row out, with a line;
- ``results.parquet`` damaged as a whole: its rows are read from ``cells/``, with a line (the
  next run rebuilds it);
- a file without digests (another tool, an older slipbench): a report reads it, its figures
  checked against the results schema's ranges, and says once that edits to it cannot be
  detected; a run neither reuses nor copies its rows.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc

from slipbench.atomic import open_parquet, whole_text
from slipbench.errors import ENVIRONMENT_ERRNOS, DataError, environment_fault
from slipbench.store.columns import out_of_range
from slipbench.store.digests import digests_of, failing, proved_whole, written_digests

RESULTS_FILE = "results.parquet"
MANIFEST = b"slipbench.cells"  # results.parquet's metadata: the cell file versions it holds
UNPROVEN = "written by another tool or an older slipbench"  # a file that carries no digests


def version(st: os.stat_result) -> list[int]:
    """A file's version: every atomic write makes a new inode, so a rewrite is seen even
    where mtime is coarse."""
    return [st.st_size, st.st_mtime_ns, st.st_ino]


class Cell(NamedTuple):
    """A cell file's row, the version of the file it came from, and whether the file carried
    its digest (False: another tool or an older slipbench wrote it; it cannot be proved)."""

    row: dict[str, Any]
    version: list[int]
    proven: bool


class Rows(Mapping[str, dict[str, Any]]):
    """A table's rows by key, turned into Python values only when a row is asked for: a read
    that finds results.parquet proved whole and its cells unchanged (a report, a cached
    rerun) never pays for the conversion, which costs more than reading the file."""

    def __init__(self, table: pa.Table, path: Path):
        self._table, self._path = table, path
        self._keys = dict.fromkeys(str(k) for k in table["key"].to_pylist())
        self._rows: dict[str, dict[str, Any]] | None = None

    def __getitem__(self, key: str) -> dict[str, Any]:
        if self._rows is None:
            self._rows = {str(r["key"]): r for r in rows_of(self._table, self._path)}
        return self._rows[key]

    def __contains__(self, key: object) -> bool:
        return key in self._keys

    def __iter__(self) -> Iterator[str]:
        return iter(self._keys)

    def __len__(self) -> int:
        return len(self._keys)


@dataclass(frozen=True)
class Held:
    """results.parquet's rows in use, as one read of the file's bytes found them."""

    source: str  # a hash of the file's bytes ("" where there is no file, or it is unreadable)
    table: pa.Table | None  # the rows in use, or None
    rows: Mapping[str, dict[str, Any]]  # them by key: proved (or, for a report, unprovable)
    digests: dict[str, str]  # the digest written for each of them
    manifest: dict[str, Any]  # the cell file versions the file records
    failed: tuple[str, ...] = ()  # keys of rows left out: they fail their digest, or (a
    # run) the file carries none
    unproven: bool = False  # the file carries no digests
    note: str = ""  # what a reader should be told of the file


@dataclass
class Scan:
    """What a results folder holds: the rows of results.parquet it uses, and the cell files'
    rows that results.parquet lacks or says otherwise."""

    results: Held
    strict: bool
    newer: dict[str, dict[str, Any]] = field(default_factory=dict)
    versions: dict[str, list[int]] = field(default_factory=dict)  # of each cell file read or held
    unreadable: dict[str, tuple[Path, str]] = field(default_factory=dict)  # damaged cell files
    notes: list[str] = field(default_factory=list)  # what a reader should be told, one line each
    unproven: list[str] = field(default_factory=list)  # files read that carry no digests

    @property
    def changed(self) -> bool:
        """Whether results.parquet must be rebuilt to hold every row, and only proved rows."""
        return bool(self.newer or self.results.failed)

    def rows(self) -> dict[str, dict[str, Any]]:
        """Every row to use, by key; a damaged cell's is left out, so that a run computes it
        again and replaces the file."""
        kept = {k: r for k, r in self.results.rows.items() if k not in self.unreadable}
        return {**kept, **self.newer}

    def _older(self) -> pa.Table | None:
        table = self.results.table
        if table is None or not self.newer:
            return table
        return table.filter(
            pc.invert(pc.is_in(table["key"], pa.array(list(self.newer), pa.string())))
        )

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
        """The digest of every row :meth:`combined` holds: as written for the rows it keeps
        (proved equal), computed for the newer ones."""
        kept = {k: d for k, d in self.results.digests.items() if k not in self.newer}
        return kept | digests_of(self.newer.values())

    def combined(self, folder: Path) -> pa.Table:
        """Every proved row as one table (protocols have different cell columns: the union is
        taken); a held row whose cell file is damaged stays: it proved itself."""
        older, newer = self._older(), union(self.newer, folder)
        if older is None:
            return newer
        try:
            return pa.concat_tables([older, newer], promote_options="permissive")
        except (pa.ArrowInvalid, pa.ArrowTypeError):
            # names the column they disagree on
            return union({**self.results.rows, **self.newer}, folder)


def scan(
    folder: Path,
    strict: bool = False,
    known: Scan | None = None,
    written: Mapping[str, Cell] | None = None,
) -> Scan:
    """results.parquet's rows that prove themselves, and every cell file whose version it does
    not hold (see the module's docstring for what is done with what cannot be proved). What
    ``known``, an earlier scan of the same kind, found is not checked again: results.parquet
    where its bytes are the same, a cell file's row where its version is; nor is a cell file
    this process ``written`` (its row as written, by key) where its version is the one written
    (reading back a run's cells was a tenth of its main process).

    Raises
    ------
    DataError
        With ``strict``, naming a damaged cell file, or rows of results.parquet that fail
        their digest with no cell file to read instead, or a figure out of its range in a file
        that carries no digests.
    """
    known = known if known is not None and known.strict == strict else None
    entries = cell_entries(folder / "cells")
    out = Scan(_held(folder / RESULTS_FILE, entries, strict, known), strict)
    held, manifest = out.results.rows, out.results.manifest
    for entry in entries:
        key = entry.name[: -len(".parquet")]
        try:
            now = version(entry.stat())
        except FileNotFoundError:
            continue  # removed since the listing
        if key in held and manifest.get(key) == now:
            out.versions[key] = now
            continue
        if known is not None and key in known.newer and known.versions.get(key) == now:
            cell = Cell(known.newer[key], now, str(entry.path) not in known.unproven)
        elif written is not None and key in written and written[key].version == now:
            cell = written[key]
        else:
            try:
                cell = read_cell(Path(entry.path), key)
            except DataError as exc:
                if strict:
                    raise
                out.unreadable[key] = (Path(entry.path), str(exc).split(": ", 1)[-1])
                continue
        if not cell.proven:
            if not strict:  # a run never reuses, nor copies, a row it cannot prove
                out.unreadable[key] = (Path(entry.path), f"it carries no digest ({UNPROVEN})")
                continue
            check_ranges([cell.row], Path(entry.path))
            out.unproven.append(entry.path)
        out.versions[key] = cell.version
        if key not in held or not same_row(cell.row, held[key]):
            out.newer[key] = cell.row
    _settle(out, folder)
    return out


def _held(path: Path, entries: list[os.DirEntry], strict: bool, known: Scan | None) -> Held:
    """results.parquet's rows that prove themselves (a report also takes those of a file
    without digests), and the cell versions the file records; ``known``'s where the file's
    bytes are those it read."""
    if not path.is_file():
        return Held("", None, {}, {}, {})
    try:
        data, _ = whole(path)
    except NotParquet as exc:  # damaged beyond its magic bytes: as any damage, the cells hold it
        damaged = read_error(exc, path, "not a readable results file")
        if not entries:
            raise damaged from None
        return _from_cells("", damaged, path)
    except OSError as exc:
        raise read_error(exc, path, "not a readable results file") from None
    source = hashlib.blake2b(data.read_buffer(), digest_size=16).hexdigest()
    data.seek(0)
    if known is not None and known.results.source == source:
        return known.results
    try:
        table = _results_table(data, path)
        digests = written_digests(table, path)
        if entries and pc.count_distinct(table["key"], mode="all").as_py() < table.num_rows:
            raise DataError(f"{path}: a key appears more than once, which slipbench never writes")
        whole_proved = digests is not None and proved_whole(table)
        rows = None if whole_proved else rows_of(table, path)
    except DataError as exc:
        if not entries:
            raise
        return _from_cells(source, exc, path)
    try:
        manifest = json.loads((table.schema.metadata or {}).get(MANIFEST, b"{}"))
    except ValueError:
        manifest = {}  # its rows are compared with the cells instead
    manifest = manifest if isinstance(manifest, dict) else {}
    if rows is None:  # every row is as written, and slipbench wrote only rows it had proved
        return Held(source, table, Rows(table, path), digests or {}, manifest)
    if digests is not None:
        bad = set(failing(rows, digests))
    else:  # a run cannot prove them, so it neither reuses nor copies them
        bad = set() if strict else {str(r["key"]) for r in rows}
    keep = [str(r["key"]) not in bad for r in rows]
    held = {str(r["key"]): r for r, k in zip(rows, keep) if k}
    return Held(
        source,
        table.filter(pa.array(keep)) if bad else table,
        held,
        {k: d for k, d in (digests or {}).items() if k in held},
        manifest,
        tuple(sorted(bad)),
        digests is None,
    )


def _results_table(data: pa.BufferReader, path: Path) -> pa.Table:
    """results.parquet's table from its bytes, with a key column."""
    try:
        table = open_parquet(data, path).read()
    except (OSError, pa.ArrowException) as exc:
        raise read_error(exc, path, "not a readable results file") from None
    table = whole_text(table, path, key="key")
    if "key" not in table.column_names:
        raise DataError(f"{path}: not a slipbench results file (no key column)")
    # pandas' notes on a table it wrote: flat rows need none, and a damaged one (a flipped bit)
    # would fail every conversion to a frame
    metadata = {k: v for k, v in (table.schema.metadata or {}).items() if k != b"pandas"}
    return table.replace_schema_metadata(metadata or None)


def _settle(out: Scan, folder: Path) -> None:
    """Say what was left out, and refuse (``strict``) what a report cannot show."""
    path, results = folder / RESULTS_FILE, out.results
    if results.note:
        out.notes.append(results.note)
    lost = [k for k in results.failed if k not in out.newer and k not in out.versions]
    if lost and out.strict:
        raise DataError(
            f"{path}: {len(lost)} row(s) fail their digest and no cell file holds them (e.g. "
            f"{', '.join(lost[:3])}): the file is damaged or was edited; rerun the command that "
            "made them to compute them again"
        )
    if lost:
        why = "carry no digests" if results.unproven else "fail their digest"
        out.notes.append(
            f"{path}: {len(lost)} row(s) {why} and no cell file holds them (e.g. "
            f"{', '.join(lost[:3])}): not used; a run that plans them computes them again"
        )
    if out.strict and results.unproven:
        check_ranges(list(results.rows.values()), path, skip=out.newer)
        out.unproven.insert(0, str(path))
    if out.strict and out.unproven:
        out.notes.append(
            f"{folder}: {len(out.unproven)} file(s) carry no digests ({UNPROVEN}; e.g. "
            f"{out.unproven[0]}): their figures are checked against the results schema, but "
            "edits to them cannot be detected"
        )
    for cell, why in out.unreadable.values():
        out.notes.append(f"{cell}: unreadable cell file, its cell will be computed again ({why})")


def check_ranges(rows: list[dict[str, Any]], path: Path | str, skip: Any = ()) -> None:
    """Refuse the first figure of ``rows`` (a file's, in its order) out of its column's range,
    but in the rows whose key is in ``skip`` (files without digests)."""
    for i, row in enumerate(rows):
        problems = [] if row.get("key") in skip else out_of_range(row)
        if problems:
            raise DataError(
                f"{path}: row {i + 1} (key {row.get('key')!r}): {problems[0]}; the file carries "
                f"no digests ({UNPROVEN}), so its figures are checked against the results schema"
            )


def cell_entries(cells: Path) -> list[os.DirEntry]:
    """The cell files of ``cells``, sorted (a hidden ``.*.tmp`` file is a write that never
    finished); none where there is no such folder."""
    try:
        return sorted(
            (
                e
                for e in os.scandir(cells)
                if e.name.endswith(".parquet") and not e.name.startswith(".")
            ),
            key=lambda e: e.name,
        )
    except FileNotFoundError:
        return []
    except OSError as exc:
        raise environment_fault(exc, cells, "read") from None


def read_table(path: Path) -> pa.Table:
    """A results file's table, its text checked (:func:`~slipbench.atomic.whole_text`)."""
    try:
        data, _ = whole(path)
    except OSError as exc:
        raise read_error(exc, path, "not a readable results file") from None
    return _results_table(data, path)


def whole(path: Path) -> tuple[pa.BufferReader, list[int]]:
    """A file's bytes and its version, from one open file.

    pyarrow given a path may open the file again for the data pages, and a concurrent
    consolidate may replace it in between (the footer of one file, the pages of another).
    Given a Python file object, it leaves work behind that can abort the interpreter at exit
    (apache/arrow#34314, #50482). In-memory bytes avoid both; results files are small.
    """
    with open(path, "rb") as fh:
        at = os.fstat(fh.fileno())
        not_parquet(fh, at.st_size)
        fh.seek(0)
        return pa.BufferReader(fh.read()), version(at)


def _from_cells(source: str, exc: Exception, path: Path) -> Held:
    """A damaged results.parquet: none of its rows in use, the cell files read instead."""
    note = f"{exc}; its rows are read from the cell files in {path.parent / 'cells'} instead"
    return Held(source, None, {}, {}, {}, note=f"{note} (a run rebuilds it)")


MAGIC = b"PAR1"  # a Parquet file's first and last 4 bytes


class NotParquet(OSError):
    """A file refused from its first and last bytes; callers say what they expected
    (:func:`read_error`: the file's fault, exit 2)."""


def not_parquet(fh: Any, size: int) -> None:
    """Refuse a file that is not Parquet from its first and last 8 bytes (its magic, and a
    footer length that fits in it), before anything else of it is read: a huge file that is
    not Parquet (a 2 GB log, a disk image) would otherwise be read whole into memory first."""
    why = ""
    if size < 2 * len(MAGIC) + 4:
        why = f"{size} bytes, too few for Parquet"
    else:
        head = fh.read(len(MAGIC))
        fh.seek(size - 8)
        tail = fh.read(8)
        footer = int.from_bytes(tail[:4], "little")
        if head != MAGIC or tail[4:] != MAGIC:
            why = "it does not begin and end with Parquet's magic bytes PAR1"
        elif footer > size - 12:
            why = f"its footer claims {footer} bytes of a {size}-byte file"
    if why:
        raise NotParquet(f"not a Parquet file: {why}; refused before reading its {size} bytes")


def read_error(exc: Exception, path: Path, what: str) -> Exception:
    """A permission or disk problem is the machine's (exit 5); anything else is the file's (exit 2)."""
    if isinstance(exc, OSError) and exc.errno in ENVIRONMENT_ERRNOS:
        return environment_fault(exc, path, "read")
    return DataError(f"{path}: {what} ({' '.join(str(exc).split())})")


def rows_of(table: pa.Table, path: Path) -> list[dict[str, Any]]:
    """The table's rows; values pyarrow cannot convert (a damaged type) are the file's fault."""
    try:
        return table.to_pylist()
    except (ValueError, OverflowError, pa.ArrowException) as exc:
        raise DataError(f"{path}: damaged values ({' '.join(str(exc).split())})") from None


def read_cell(path: Path, key: str) -> Cell:
    """One cell file's row, proved by its digest where it carries one.

    Raises
    ------
    DataError
        Naming the file: unreadable, not one row keyed by its name, or a row that fails its
        digest (the file is damaged, or was edited).
    """
    try:
        data, at = whole(path)
        table = open_parquet(data, path).read()  # half read_table's cost for one row
    except (OSError, pa.ArrowException) as exc:
        raise read_error(exc, path, "not a readable cell file") from None
    rows = rows_of(whole_text(table, path), path)
    if len(rows) != 1 or rows[0].get("key") != key:
        raise DataError(
            f"{path}: a cell file holds one row whose key is its name, found "
            f"{len(rows)} row(s){'' if not rows else ' with key ' + repr(rows[0].get('key'))}"
        )
    digests = written_digests(table, path)
    if digests is not None and failing(rows, digests):
        raise DataError(
            f"{path}: its row is not what slipbench wrote (it fails its digest: the file is "
            "damaged, or was edited)"
        )
    return Cell(rows[0], at, digests is not None)


def same(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a == b


def same_row(cell: dict[str, Any], stored: dict[str, Any]) -> bool:
    """Whether results.parquet's row says what the cell file says. Its other columns (of other
    protocols' cells) must be empty; ints it promoted to floats compare equal."""
    return all(same(v, stored.get(k)) for k, v in cell.items()) and all(
        v is None for k, v in stored.items() if k not in cell
    )


def union(rows: dict[str, dict[str, Any]], folder: Path) -> pa.Table:
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
