"""A table's digest (results.parquet proved whole) and a column's (the history's index): the
same for a table as written and as Parquet gives it back, whatever its chunks, and another for
any change of a value, a null, a name, a type or a slipbench metadata entry."""

from __future__ import annotations

import datetime as dt
import math

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from slipbench.store.digests import (
    DIGESTS,
    TABLE,
    column_digest,
    proved_whole,
    table_digest,
    with_table_digest,
)

COLUMNS = {
    "int": pa.array([1, None, 3]),
    "float": pa.array([0.5, None, math.nan]),
    "text": pa.array(["holweg", None, "é"]),
    "large text": pa.array(["a", "", None], pa.large_string()),
    "bool": pa.array([True, None, False]),
    "all null": pa.array([None, None, None]),
    "time": pa.array([dt.datetime(2024, 6, 11), None, dt.datetime(2025, 1, 1)], pa.timestamp("us")),
    "list": pa.array([[1, 2], None, []]),
    "struct": pa.array([{"x": 1}, None, {"x": 2}]),
}


def _table() -> pa.Table:
    return pa.table(COLUMNS).replace_schema_metadata(
        {DIGESTS: b'{"a":"0123"}', b"slipbench.cells": b"{}", b"pandas": b"{}"}
    )


def _round_trip(table: pa.Table) -> pa.Table:
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink)
    return pq.read_table(pa.BufferReader(sink.getvalue()))


def test_a_table_reads_back_from_parquet_with_its_digest_whatever_its_chunks():
    table = _table()
    chunked = pa.concat_tables([table.slice(0, 1), table.slice(1, 1), table.slice(2)])
    assert chunked[0].num_chunks == 3
    for other in (_round_trip(table), chunked, _round_trip(chunked)):
        assert table_digest(other) == table_digest(table)
        assert all(column_digest(other[c]) == column_digest(table[c]) for c in COLUMNS)
    assert proved_whole(_round_trip(with_table_digest(table)))


def _set(table: pa.Table, column: str, values: list, kind: pa.DataType | None = None) -> pa.Table:
    at = table.column_names.index(column)
    return table.set_column(at, column, pa.array(values, kind or table.schema.field(at).type))


CHANGES = {
    "a value": lambda t: _set(t, "int", [1, None, 4]),
    "a null": lambda t: _set(t, "float", [0.5, 0.0, math.nan]),
    "a null made a value": lambda t: _set(t, "text", ["holweg", "", "é"]),
    "a text's split": lambda t: _set(t, "text", ["holwe", "g", "é"]),
    "a nested value": lambda t: _set(t, "list", [[1, 3], None, []]),
    "a type": lambda t: _set(t, "int", [1, None, 3], pa.int32()),
    "a name": lambda t: t.rename_columns(["integer", *t.column_names[1:]]),
    "two columns swapped": lambda t: t.select([1, 0, *range(2, t.num_columns)]),
    "the rows' order": lambda t: t.take([1, 0, 2]),
    "a row digest": lambda t: t.replace_schema_metadata(
        {**t.schema.metadata, DIGESTS: b'{"a":"0124"}'}
    ),
    "a slipbench entry removed": lambda t: t.replace_schema_metadata({DIGESTS: b'{"a":"0123"}'}),
}


@pytest.mark.parametrize("change", list(CHANGES))
def test_any_change_changes_the_digest(change):
    table = with_table_digest(_table())
    changed = CHANGES[change](table)
    assert table_digest(changed) != table_digest(table)
    assert proved_whole(table) and not proved_whole(_round_trip(changed))


def test_metadata_not_slipbench_s_is_not_digested():
    """pandas' notes, which a reader drops (a flipped bit there is not in any row)."""
    table = _table()
    other = table.replace_schema_metadata({**table.schema.metadata, b"pandas": b"x"})
    assert table_digest(other) == table_digest(table)


@pytest.mark.parametrize(
    "entry", [None, b"not json", b'{"format": 2, "digest": "x"}', b'["format", 1]']
)
def test_a_table_without_a_digest_of_this_format_is_not_proved_whole(entry):
    table = with_table_digest(_table())
    metadata = {k: v for k, v in table.schema.metadata.items() if k != TABLE}
    if entry is not None:
        metadata[TABLE] = entry
    assert not proved_whole(table.replace_schema_metadata(metadata))


def test_a_column_digest_is_pinned():
    """The history's index stores these digests: a change to them would rebuild every index."""
    columns = {
        "b898db0f61c21186": pa.chunked_array([["holweg", None], ["", "é"]]),
        "d25358cf484acb93": pa.chunked_array([[1, None], [3, 4]]),
        "b374fe9a8805f25b": pa.chunked_array([[0.5, None], [math.nan, -0.0]]),
        "1bf04773168aa289": pa.chunked_array([[True, None], [False, True]]),
    }
    assert {column_digest(c): d for d, c in columns.items()} == {d: d for d in columns}
