"""Rows that prove themselves: a digest of each result row, written in the Parquet metadata of
the file that holds it (a cell file's one row, every row of ``results.parquet``) and checked on
every read.

A digest is of the row's canonical content (:func:`row_digest`), not of the file's bytes, so a
flipped bit anywhere in a value, a column's name or the digests themselves, and a row rewritten
with its metadata kept (another value, the same digest), all read as a row that is not what
slipbench wrote. A digest detects damage and casual edits; it is not a signature: whoever
recomputes it with this module can forge a row.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import pyarrow as pa

from slipbench.errors import DataError
from slipbench.store.keys import canonical, canonical_json

#: the Parquet metadata key of a file's row digests: a JSON object {key: digest}
DIGESTS = b"slipbench.rows"


def row_digest(row: dict[str, Any]) -> str:
    """A digest of what a result row says: its non-null values, canonical, so that the row as
    a cell file holds it and as results.parquet holds it (where a column of other protocols'
    cells is null, or an int column was promoted to float) digest alike."""
    present = {str(k): v for k, v in row.items() if v is not None}
    try:
        text = canonical_json(present)
    except (TypeError, ValueError):  # a value of another kind, which slipbench never writes
        text = canonical_json({k: _plain(v) for k, v in present.items()})
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _plain(value: Any) -> Any:
    """A value as :func:`~slipbench.store.keys.canonical` takes it, or else by its text."""
    try:
        canonical(value)
        return value
    except (TypeError, ValueError):
        return str(value)


def digests_of(rows: Iterable[dict[str, Any]]) -> dict[str, str]:
    """Each row's :func:`row_digest`, by its key."""
    return {str(r["key"]): row_digest(r) for r in rows}


def with_digests(table: pa.Table, digests: dict[str, str], **more: str) -> pa.Table:
    """``table`` with ``digests`` (and ``more`` metadata, by its key's bytes) in its metadata."""
    metadata = {DIGESTS: json.dumps(digests, separators=(",", ":"), sort_keys=True)}
    metadata |= {k.encode(): v for k, v in more.items()}
    return table.replace_schema_metadata(metadata)


def written_digests(table: pa.Table, path: Path) -> dict[str, str] | None:
    """The row digests a file was written with; None where it carries none (another tool, or
    an older slipbench wrote it).

    Raises
    ------
    DataError
        Where the entry is there but is not a JSON object of digests (the file is damaged).
    """
    text = (table.schema.metadata or {}).get(DIGESTS)
    if text is None:
        return None
    try:
        found = json.loads(text)
    except ValueError:  # UnicodeDecodeError too
        found = None
    if not isinstance(found, dict) or not all(isinstance(v, str) for v in found.values()):
        raise DataError(f"{path}: its row digests are damaged (not a JSON object of digests)")
    return found


def failing(rows: Iterable[dict[str, Any]], digests: dict[str, str]) -> list[str]:
    """The keys of ``rows`` whose digest is not the one written for them (none written: fails)."""
    return [str(r.get("key")) for r in rows if digests.get(str(r.get("key"))) != row_digest(r)]
