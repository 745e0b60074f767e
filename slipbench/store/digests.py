"""Rows that prove themselves: a digest of each result row, written in the Parquet metadata of
the file that holds it (a cell file's one row, every row of ``results.parquet``), and a digest
of a whole table (:func:`table_digest`) that ``results.parquet`` carries beside them.

A row digest is of the row's canonical content (:func:`row_digest`), not of the file's bytes,
so a row proves itself wherever it travels: a cell's digest is the digest of its row in
``results.parquet`` too (where a column of other protocols' cells is null, or an int column was
promoted to float), and a flipped bit anywhere in a value, a column's name or the digests
themselves, and a row rewritten with its metadata kept (another value, the same digest), all
read as a row that is not what slipbench wrote.

Building each row's canonical text costs 25 ns a byte, seven times what reading the file costs,
so a file of many rows is proved whole instead: its table digest hashes Arrow's buffers column
by column (names, types, which values are null, the values' bytes) and its ``slipbench.*``
metadata (the row digests among them). Where it matches, every row is what slipbench wrote and
wrote only after proving it; where it fails, or a file has none (an older slipbench wrote it),
each row is checked against its own digest, so that the rows still intact are kept and the
others named. A digest detects damage and casual edits; it is not a signature: whoever
recomputes it with this module can forge a row.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from slipbench.errors import DataError
from slipbench.store.keys import canonical, canonical_json

#: the Parquet metadata key of a file's row digests: a JSON object {key: digest}
DIGESTS = b"slipbench.rows"
#: the Parquet metadata key of a table's digest: a JSON object {"format": 1, "digest": hex}
TABLE = b"slipbench.table"
#: what :func:`table_digest` hashes and how; a file of another format is proved row by row
TABLE_FORMAT = 1


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


def _nested(column: pa.ChunkedArray | pa.Array) -> bool:
    """Whether a column's type has no one plain buffer of values (lists, structs: none that
    slipbench writes); Parquet gives such a type back under other names (``list<element:``)."""
    kind = column.type
    return not (
        pa.types.is_string(kind)
        or pa.types.is_large_string(kind)
        or pa.types.is_primitive(kind)
        or pa.types.is_null(kind)
    )


def _parts(chunk: pa.Array) -> Iterator[tuple[int, bytes | memoryview]]:
    """What a digest of a chunk of a column hashes, each part with its stream: 0 which rows are
    null, 1 a text's lengths, 2 the values' bytes (a nested type's canonical text)."""
    if _nested(chunk):
        yield 2, canonical_json({"values": [_plain(v) for v in chunk.to_pylist()]}).encode()
        return
    text = pa.types.is_string(chunk.type) or pa.types.is_large_string(chunk.type)
    if pa.types.is_temporal(chunk.type):  # its integers: fill_null takes no 0 for a time
        chunk = chunk.view(pa.int64() if chunk.type.bit_width == 64 else pa.int32())
    if chunk.null_count:
        yield 0, chunk.is_null().to_numpy(zero_copy_only=False).tobytes()
        if not text and not pa.types.is_null(chunk.type):  # what is under a null is undefined
            chunk = pc.fill_null(chunk, False if pa.types.is_boolean(chunk.type) else 0)
    else:
        yield 0, bytes(len(chunk))
    if text:
        width = np.int64 if pa.types.is_large_string(chunk.type) else np.int32
        ends = np.frombuffer(chunk.buffers()[1], width)[
            chunk.offset : chunk.offset + len(chunk) + 1
        ]
        yield 1, np.diff(ends).astype(np.int32).tobytes()
        if len(chunk) and chunk.buffers()[2] is not None:
            yield 2, memoryview(chunk.buffers()[2])[ends[0] : ends[-1]]
    elif not pa.types.is_null(chunk.type):
        yield 2, chunk.to_numpy(zero_copy_only=False).tobytes()


def column_digest(column: pa.ChunkedArray) -> str:
    """A digest of a column's values whatever its chunks: its type, which rows are null, and
    its values' bytes (a text's lengths and bytes). Hashing Arrow's buffers costs a 3-million-row
    index a second where a digest per row in Python would cost minutes. A dictionary column
    (text read as codes) digests as its values do, a chunk decoded at a time."""
    kind, chunks = column.type, iter(column.chunks)
    if pa.types.is_dictionary(kind):
        kind, chunks = kind.value_type, (c.dictionary_decode() for c in column.chunks)
    elif _nested(column):
        (_, text), *_ = _parts(column.combine_chunks())
        return hashlib.sha256(b"nested:" + bytes(text)).hexdigest()[:16]
    streams = [hashlib.sha256() for _ in range(3)]
    for chunk in chunks:
        for stream, part in _parts(chunk):
            streams[stream].update(part)
    parts = [str(kind).encode(), *(s.digest() for s in streams)]
    return hashlib.sha256(b"".join(parts)).hexdigest()[:16]


def table_digest(table: pa.Table) -> str:
    """A digest of all a table holds (see the module's docstring): each column's name, type
    and values (as :func:`column_digest` sees them), in order, and its metadata entries named
    ``slipbench.*`` but :data:`TABLE` (its row digests, a results file's manifest).

    One hash over every part, each prefixed by its length (a column's chunks combined first,
    so that the parts do not depend on them): a quarter of the cost of a :func:`column_digest`
    per column, which is what reading a wide file would otherwise pay most for.
    """
    digest = hashlib.sha256()

    def put(part: bytes | memoryview) -> None:
        digest.update(len(part).to_bytes(8, "little"))
        digest.update(part)

    metadata = table.schema.metadata or {}
    for name in sorted(k for k in metadata if k.startswith(b"slipbench.") and k != TABLE):
        put(name)
        put(metadata[name])
    for name, column in zip(table.column_names, table.columns):
        put(name.encode())
        put(b"nested" if _nested(column) else str(column.type).encode())
        chunk = column.chunk(0) if column.num_chunks == 1 else column.combine_chunks()
        for stream, part in _parts(chunk):
            put(bytes([stream]))
            put(part)
    return digest.hexdigest()[:32]


def with_table_digest(table: pa.Table) -> pa.Table:
    """``table`` with its :func:`table_digest` in its metadata (after every other entry)."""
    entry = json.dumps({"format": TABLE_FORMAT, "digest": table_digest(table)})
    return table.replace_schema_metadata({**(table.schema.metadata or {}), TABLE: entry})


def proved_whole(table: pa.Table) -> bool:
    """Whether ``table`` is as it was written, by the table digest in its metadata: False where
    it carries none, one of another format or a damaged one, or its content differs (check
    its rows one by one then)."""
    try:
        entry = json.loads((table.schema.metadata or {})[TABLE])
    except (KeyError, ValueError):  # UnicodeDecodeError too
        return False
    if not isinstance(entry, dict) or entry.get("format") != TABLE_FORMAT:
        return False
    return entry.get("digest") == table_digest(table)
