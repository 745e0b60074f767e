"""Fields joined from a lab's metadata files (``[[metadata]]`` in the mapping): a CSV, JSON or
TOML file beside the recordings, one for all files (a row per recording, found by a key column)
or one per recording or folder (its path a template), e.g. the sampling rate a logger wrote
into ``session/info.json``."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import tomllib

from slipbench.data.importers.paths import check_inside, check_relative
from slipbench.data.importers.tables import line_of, read_csv
from slipbench.errors import TOO_DEEP, DataError, UsageError

METADATA_KEYS = {"table", "key", "match", "fields"}
TABLE_CSV = {"delimiter": ",", "comment": "#", "skip_rows": 0}


@dataclass(frozen=True)
class MetadataTable:
    """One ``[[metadata]]`` entry: where the table is, how a file finds its record, which
    columns give which fields."""

    name: str
    table: str  # a template, relative to SRC
    key: str | None  # the column naming the recording; None: the table is one record
    match: str  # a template: the value of ``key`` that names this file
    fields: dict[str, str]  # field -> column


def parse_metadata(raw: Any, where: str, fields: tuple[str, ...]) -> tuple[MetadataTable, ...]:
    """The checked ``[[metadata]]`` entries of a mapping."""
    if not isinstance(raw, list):
        raise UsageError(f"{where}: metadata must be an array of tables: [[metadata]]")
    out = []
    for i, entry in enumerate(raw):
        name = f"[[metadata]] #{i + 1}"
        if not isinstance(entry, dict):
            raise UsageError(f"{where}: {name} must be a table")
        unknown = sorted(set(entry) - METADATA_KEYS)
        if unknown:
            raise UsageError(
                f"{where}: unknown key {unknown[0]!r} in {name} (known: {', '.join(sorted(METADATA_KEYS))})"
            )
        for key in ("table", "key", "match"):
            if key in entry and not isinstance(entry[key], str):
                raise UsageError(f"{where}: {name}.{key} must be a string")
        if "table" not in entry:
            raise UsageError(f"{where}: {name} needs table = '...' (a path relative to SRC)")
        columns = entry.get("fields")
        if not isinstance(columns, dict) or not columns:
            raise UsageError(
                f"{where}: {name} needs fields = {{ field = 'column', ... }}, e.g. "
                "{ sampling_rate_hz = 'rate' }"
            )
        for field, column in columns.items():
            if field not in fields:
                raise UsageError(
                    f"{where}: {name}.fields: {field!r} is not a field (fields: {', '.join(fields)})"
                )
            if not isinstance(column, str):
                raise UsageError(f"{where}: {name}.fields.{field} must be a column name")
        if "match" in entry and "key" not in entry:
            raise UsageError(f"{where}: {name}.match needs key: the column it is looked up in")
        out.append(
            MetadataTable(
                name, entry["table"], entry.get("key"), entry.get("match", "{file}"), dict(columns)
            )
        )
    return tuple(out)


Record = tuple[dict[str, Any], str]  # a record's values, and where it is (file, line)


def _records(path: Path) -> list[Record]:
    """The records of a metadata file: a CSV's rows, a JSON object or list of objects, a TOML
    table or its one array of tables."""
    suffix = path.suffix.lower()
    if suffix == ".csv":
        frame = read_csv(path, TABLE_CSV, [], min_rows=1, text=True)
        return [
            (
                {k: v if isinstance(v, str) else "" for k, v in row.items()},  # empty: NaN
                f"{path}: line {line_of(path, i, TABLE_CSV)}",
            )
            for i, row in enumerate(frame.to_dict("records"))
        ]
    try:
        text = path.read_text(encoding="utf-8")
        data = (
            json.loads(text, object_pairs_hook=_once) if suffix == ".json" else tomllib.loads(text)
        )
    except OSError as exc:
        raise DataError(f"{path}: cannot read ({exc.strerror or exc})") from None
    except (ValueError, UnicodeDecodeError) as exc:  # JSON and TOML errors are ValueErrors
        raise DataError(
            f"{path}: not valid {suffix[1:].upper()} ({' '.join(str(exc).split())})"
        ) from None
    except RecursionError:
        raise DataError(f"{path}: {TOO_DEEP}") from None
    if suffix == ".toml":
        arrays = [
            v
            for v in data.values()
            if isinstance(v, list) and v and all(isinstance(r, dict) for r in v)
        ]
        data = arrays[0] if len(arrays) == 1 else data
    if isinstance(data, dict):
        return [(data, str(path))]
    if isinstance(data, list) and all(isinstance(r, dict) for r in data):
        return [(r, f"{path}: record #{i + 1}") for i, r in enumerate(data)]
    raise DataError(f"{path}: a metadata file holds an object (one record) or a list of objects")


def _once(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """A JSON object whose keys are all distinct (json keeps the last of a repeated key silently;
    TOML refuses one itself)."""
    seen: dict[str, Any] = {}
    for key, value in pairs:
        if key in seen:
            raise ValueError(f"key {key!r} is given twice in one object (which value holds?)")
        seen[key] = value
    return seen


class MetadataReader:
    """Looks up each file's record in the mapping's metadata tables; reads each table once."""

    def __init__(
        self, src: Path, where: str, imported: set[str], outside: Sequence[Path] | None = ()
    ) -> None:
        self.src, self.where, self.imported, self.outside = src, where, imported, outside
        self._cache: dict[Path, list[Record]] = {}

    def fields(self, entry: MetadataTable, rel: str, fill) -> dict[str, Any]:
        """The fields ``entry`` gives file ``rel``; ``fill`` fills a template for this file."""
        table_rel = fill(entry.table, f"{entry.name}.table")
        if table_rel in self.imported:
            raise UsageError(
                f"{self.where}: {entry.name}: the table {table_rel} is also selected as a recording by files; narrow files"
            )
        path = self.src / table_rel
        named = f"{self.where}: {entry.name}.table = {entry.table!r} (for {rel})"
        check_relative(table_rel, named, self.outside)
        check_inside(path, self.src, named, self.outside)
        if path.suffix.lower() not in (".csv", ".json", ".toml"):
            raise UsageError(
                f"{self.where}: {entry.name}.table: {table_rel} is not a .csv, .json or .toml file"
            )
        if path not in self._cache:
            if not path.is_file():
                raise DataError(f"{path}: not found ({entry.name}.table for {rel})")
            self._cache[path] = _records(path)
        records = self._cache[path]
        if entry.key is None:
            if len(records) != 1:
                raise DataError(
                    f"{path}: {len(records)} records; without {entry.name}.key the table must hold one (for {rel})"
                )
            record, at = records[0]
        else:
            wanted = fill(entry.match, f"{entry.name}.match")
            found = [(r, at) for r, at in records if _plain(r.get(entry.key)) == wanted]
            if not found:
                present = (
                    ""
                    if any(entry.key in r for r, _ in records)
                    else f" (it has no column {entry.key!r})"
                )
                raise DataError(
                    f"{path}: no record with {entry.key} = {wanted!r}, for {rel}{present}"
                )
            if len(found) > 1:
                raise DataError(
                    f"{found[0][1]} and {found[1][1]}: both have {entry.key} = {wanted!r}"
                )
            record, at = found[0]
        out = {}
        for field, column in entry.fields.items():
            if column not in record:
                raise DataError(
                    f"{at}: no {column!r}, which {entry.name} reads as {field} for {rel}"
                )
            value = record[column]
            if isinstance(value, bool) or not isinstance(value, (str, int, float)):
                raise DataError(
                    f"{at}: {column} = {value!r} is not a string or a number ({field} of {rel})"
                )
            out[field] = value
        return out


def _plain(value: Any) -> str | None:
    """A key value as text: 3 and "3" both match "3"."""
    if value is None or (isinstance(value, float) and np.isnan(value)):
        return None
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value)
