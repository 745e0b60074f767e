"""The results schema: one declaration of every column, the page written from it, and a store
that refuses rows it does not declare."""

from __future__ import annotations

from pathlib import Path

import pytest
import results_columns  # docs/tools, on pytest's pythonpath

from slipbench.store import columns
from slipbench.store.results import ResultsStore

ROOT = Path(__file__).resolve().parents[2]


def test_committed_page_is_what_the_generator_writes():
    page = (ROOT / "docs" / "reference" / "results-columns.md").read_text()
    assert page == results_columns.page(), (
        "docs/reference/results-columns.md is stale: "
        "python docs/tools/results_columns.py > docs/reference/results-columns.md"
    )


def test_every_column_is_declared_once_with_a_known_type():
    names = [c.name for group in columns.GROUPS.values() for c in group]
    assert len(names) == len(set(names))
    assert {c.type for c in columns.COLUMNS.values()} == {"string", "int64", "float64", "bool"}
    assert all(c.meaning for c in columns.COLUMNS.values())


def test_a_figure_is_one_entry_with_its_interval_columns():
    figure = columns.Figure("f1", "fraction", "harmonic mean", se=True)
    assert [c.name for c in figure.columns()] == ["f1", "f1_lo", "f1_hi", "f1_se"]
    streamed = [c.name for c in columns.Figure("x", "ms", "a", operating=True).columns()]
    assert streamed == ["x", "x_lo", "x_hi", "op_x", "op_x_lo", "op_x_hi"]


ROW = {
    "key": "k1",
    "protocol": "window-size",
    "detector": "holweg",
    "status": "ok",
    "cell": '{"window": 50, "material": "felt"}',
    "material": "felt",  # a cell-key column of the protocol: its cell names it
    "window": 50,
    "accuracy": 0.75,
    "low_n": False,
    "epochs": None,
}


def test_the_store_writes_a_declared_row(tmp_path):
    store = ResultsStore(tmp_path)
    store.put(dict(ROW))
    assert set(store.finished()) == {"k1"}


@pytest.mark.parametrize(
    "change, said",
    [
        ({"accuracy_typo": 0.5}, "accuracy_typo: not a declared results column"),
        ({"window": "50"}, "window: '50' is not a int64"),
        ({"low_n": 1}, "low_n: 1 is not a bool"),
        ({"n_test": True}, "n_test: True is not a int64"),
        ({"accuracy": 1.5}, r"accuracy 1.5 is not in \[0, 1\]"),
        ({"accuracy": float("nan")}, "accuracy nan is not a finite number"),
        ({"n_test": -1}, "n_test -1 is not >= 0"),
        ({"seed": 2**32}, r"seed 4294967296 is not in \[0, 4294967295\]"),
    ],
)
def test_the_store_refuses_what_the_schema_does_not_declare(tmp_path, change, said):
    store = ResultsStore(tmp_path)
    with pytest.raises(TypeError, match=said):
        store.put({**ROW, **change})
    assert not any(tmp_path.rglob("*.parquet"))  # nothing half-written


def test_every_fraction_and_count_declares_its_range():
    """A rate, a share or an area lies in [0, 1] and a count is >= 0, so that a file without
    digests can be checked: a new column of such a unit must say so."""
    for column in columns.COLUMNS.values():
        if column.unit == "fraction":
            assert column.bounds == (0.0, 1.0), column.name
        if column.unit in ("windows", "trials", "ms", "s", "us", "1/min", "min"):
            assert column.bounds[0] >= 0, column.name
    assert columns.COLUMNS["accuracy"].finite and not columns.COLUMNS["accuracy_lo"].finite
    assert columns.COLUMNS["accuracy_lo"].problem(float("nan")) is None  # an interval may be NaN


def test_a_column_role_is_one_field_every_identity_list_follows(monkeypatch):
    """A new setting is one schema entry: the factors' settings, the contrast's and the input
    twins' pairing and the history's series read it from there (queried when asked)."""
    new = columns.Column("grip", "string", "", "how the object was held", role=columns.SETTING)
    keyed = columns.Column(
        "grip", "string", "", "how the object was held", role=columns.SETTING, keys=("grip",)
    )
    assert "grip" not in columns.identity(columns.SETTING)
    monkeypatch.setitem(columns.COLUMNS, "grip", new)
    assert columns.identity(columns.SETTING)[-1] == "grip"
    assert "grip" not in columns.identity(columns.SETTING, keyed=True)
    monkeypatch.setitem(columns.COLUMNS, "grip", keyed)
    assert "grip" in columns.identity(columns.READING, columns.SETTING, keyed=True, follows=False)
    assert columns.recording("grip") == ("grip",)
    assert "grip" in columns.key_columns()


def test_the_identity_queries_say_what_is_wrong():
    with pytest.raises(ValueError, match="not a column role"):
        columns.identity("settng")
    with pytest.raises(ValueError, match="records the key field"):
        columns.recording("nowhere")
    # what the queries give today, so that a role moved by mistake shows
    assert columns.identity(columns.ENTRANT, columns.READING) == (
        "detector",
        "detector_params",
        "normalize",
        "input",
    )
    assert columns.recording("test", "stream") == ("test_sensors", "test_where", "test_stream")
    # what tables, pairings and sorts name a result by, in this order (compare's JSON keeps it)
    assert columns.identity(*columns.ROLES, named=True) == (
        "protocol",
        "detector",
        "split",
        "seed",
        "cell",
    )
    assert columns.ENTRANT_CELL == ("protocol", "detector", "cell")
    assert set(columns.identity(columns.SETTING, follows=True)) == {
        "train_dataset_fingerprint",
        "test_dataset_fingerprint",
        "sensor_map",
    }
