"""Two faults of a Parquet file's column names, for every reader's tests: a name a flipped bit
made invalid UTF-8, and a name given to two columns."""

from __future__ import annotations

import pyarrow as pa


def name_not_utf8(data: bytes, name: str) -> bytes:
    """``data`` (a whole Parquet file) with the first byte of column ``name`` in its footer's
    schema set to 0xFF, as a flipped bit would leave it: the schema element (Thrift: the
    name's length, then its bytes) comes before the column chunks' paths and the metadata."""
    footer = len(data) - 8 - int.from_bytes(data[-8:-4], "little")
    encoded = name.encode()
    at = data.index(bytes([len(encoded)]) + encoded, footer) + 1
    return data[:at] + b"\xff" + data[at + 1 :]


def name_twice(table: pa.Table, keep: int, rename: int) -> pa.Table:
    """``table`` with column ``rename`` given the name of column ``keep`` (metadata kept)."""
    names = list(table.column_names)
    names[rename] = names[keep]
    return table.rename_columns(names)
