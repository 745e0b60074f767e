"""A results file given to `report` on its own: rows deleted, added or edited, or columns
swapped, are refused (exit 2) naming what does not match; cells the file lacks are warned of."""

from __future__ import annotations

import shutil

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from storegen import repeats_store

from slipbench.store.results import ResultsStore, read_results, row_digest


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("results") / "run"
    repeats_store(folder, seeds=(0, 1))
    return folder


def _swapped(table: pa.Table, a: str, b: str) -> pa.Table:
    names = table.column_names
    columns = [table.column(n) for n in names]
    i, j = names.index(a), names.index(b)
    columns[i], columns[j] = columns[j], columns[i]
    return pa.Table.from_arrays(columns, names=names).replace_schema_metadata(table.schema.metadata)


def test_the_file_as_written_reads_whole(folder):
    rows = read_results(folder / "results.parquet")
    assert len(rows) == 8 and rows.set_index("key").equals(read_results(folder).set_index("key"))


def test_deleted_rows_are_refused(folder, tmp_path, cli):
    table = pq.read_table(folder / "results.parquet")
    copy = tmp_path / "run"
    shutil.copytree(folder, copy)
    pq.write_table(table.slice(0, 5), copy / "results.parquet")  # its metadata kept
    code, _, err = cli(["report", str(copy / "results.parquet")])
    assert code == 2
    assert "3 row(s) written to it are missing" in err and "give the folder instead" in err
    # the folder itself reads whole: cells/ hold the truth
    assert len(read_results(copy)) == 8


def test_swapped_columns_are_refused_naming_them(folder, tmp_path, cli):
    table = pq.read_table(folder / "results.parquet")
    copy = tmp_path / "run"
    shutil.copytree(folder, copy)
    pq.write_table(_swapped(table, "accuracy", "tp_rate"), copy / "results.parquet")
    code, _, err = cli(["report", str(copy / "results.parquet")])
    assert code == 2
    assert "8 row(s) edited since they were written" in err
    assert "accuracy" in err and "tp_rate" in err and "in cells/" in err
    # without its folder, the digests written with the rows still tell
    alone = tmp_path / "alone.parquet"
    shutil.copy(copy / "results.parquet", alone)
    code, _, err = cli(["report", str(alone)])
    assert code == 2 and "8 row(s) edited" in err and "its content is not what was written" in err


def test_a_table_rewritten_by_pandas_is_held_to_its_cells(folder, tmp_path):
    copy = tmp_path / "run"
    shutil.copytree(folder, copy)
    rows = pd.read_parquet(copy / "results.parquet")
    rows.loc[0, "accuracy"] = 0.99  # pandas keeps no slipbench metadata
    rows.to_parquet(copy / "edited.parquet")
    with pytest.raises(Exception, match=r"1 row\(s\) edited .*accuracy 0\.99 here"):
        read_results(copy / "edited.parquet")
    rows.iloc[1:].to_parquet(tmp_path / "elsewhere.parquet")  # no metadata, no cells: as it is
    assert len(read_results(tmp_path / "elsewhere.parquet")) == 7


def test_cells_the_file_lacks_are_warned_of(folder, tmp_path):
    copy = tmp_path / "run"
    shutil.copytree(folder, copy)  # a copy: other inodes, read and found the same
    assert len(read_results(copy / "results.parquet")) == 8
    row = read_results(copy).iloc[0].to_dict()
    ResultsStore(copy).put({**row, "key": "newcell", "seed": 9})  # not consolidated
    with pytest.warns(UserWarning, match=r"1 finished cell\(s\) .* not in this file"):
        assert len(read_results(copy / "results.parquet")) == 8


def test_digests_hold_across_promotion():
    """A row digests alike as its cell file and as results.parquet holds it (a column of other
    protocols' cells null, an int promoted to float)."""
    cell = {"key": "k", "seed": 1, "accuracy": 0.5, "window": 50}
    assert row_digest(cell) == row_digest({**cell, "window": 50.0, "material": None})
    assert row_digest(cell) != row_digest({**cell, "accuracy": 0.6})
