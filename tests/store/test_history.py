"""The history store: runs added once and kept as written, read back in order, the index a
cache, bad input refused with a clear message."""

from __future__ import annotations

import pandas as pd
import pyarrow.parquet as pq
import pytest
from historygen import run_folder

from slipbench.app.cli import main
from slipbench.atomic import write_atomic
from slipbench.errors import DataError, UsageError
from slipbench.history.series import series_rows
from slipbench.store.history import (
    INDEX_FILE,
    Run,
    add_run,
    check_commit,
    read_history,
    run_path,
    run_table,
    utc_date,
)
from slipbench.store.results import read_results


def _cli(*args: str) -> int:
    with pytest.raises(SystemExit) as exit_:
        main(list(args))
        raise SystemExit(0)
    return int(exit_.value.code or 0)


def _files(folder):
    return {
        p.relative_to(folder): (p.stat().st_mtime_ns, p.read_bytes())
        for p in folder.rglob("*")
        if p.is_file()
    }


def test_add_keeps_each_run_once_and_reads_them_in_date_order(tmp_path):
    hist = tmp_path / "hist"
    for i, date in enumerate(("2026-02-03", "2026-01-05T10:00:00+02:00", "2026-01-20")):
        run_folder(tmp_path / f"r{i}", seed=i, code=f"code-{i}")
        assert (
            _cli(
                "history",
                "add",
                str(tmp_path / f"r{i}"),
                "--history",
                str(hist),
                "--commit",
                f"c{i}",
                "--date",
                date,
                "--machine",
                "ci runner ü",
            )
            == 0
        )
    before = _files(hist)
    # the same commit again, even with other rows: nothing changes
    run_folder(tmp_path / "other", seed=9, shift=0.3)
    assert (
        _cli("history", "add", str(tmp_path / "other"), "--history", str(hist), "--commit", "c0")
        == 0
    )
    assert _files(hist) == before
    frame = read_history(hist)
    assert len(frame) == 3 * 48
    runs = frame.groupby("run")[["commit", "date"]].first()
    assert list(runs["commit"]) == ["c1", "c2", "c0"]  # by date, zones made UTC
    assert runs["date"].iloc[0] == "2026-01-05T08:00:00Z"
    assert set(frame["machine"]) == {"ci runner ü"}
    assert frame["bench_digest"].eq("").all()
    assert frame.groupby("run")["code_identity"].first().tolist() == ["code-1", "code-2", "code-0"]
    # one series per cell, the same in every run: the code and seed are not part of it
    assert frame["series"].nunique() == 48
    assert frame.groupby("series")["run"].nunique().eq(3).all()
    assert list(hist.glob("runs/month=*/*.parquet"))  # hive-partitioned by month
    assert sorted(p.name for p in (hist / "runs").iterdir()) == ["month=2026-01", "month=2026-02"]


def test_the_index_is_a_cache_of_the_runs(tmp_path):
    hist = tmp_path / "hist"
    for i in range(2):
        rows = series_rows(read_results(run_folder(tmp_path / f"r{i}", seed=i, code=f"k{i}")))
        add_run(hist, rows, Run(f"c{i}", utc_date(f"2026-01-0{i + 1}"), "m"))
    whole = read_history(hist)
    (hist / INDEX_FILE).unlink()
    assert read_history(hist).equals(whole)  # read from the run files
    rows = series_rows(read_results(run_folder(tmp_path / "r2", seed=2, code="k2")))
    add_run(hist, rows, Run("c2", utc_date("2026-01-03"), "m"))
    index = pq.read_table(hist / INDEX_FILE)
    assert index.num_rows == 3 * 48  # rebuilt with every run
    assert read_history(hist, ["accuracy"]).shape == (3 * 48, 4 + 1 + 1)


def test_a_run_file_edited_after_it_was_written_is_refused(tmp_path):
    hist = tmp_path / "hist"
    rows = series_rows(read_results(run_folder(tmp_path / "r0", seed=0)))
    path = add_run(hist, rows, Run("c0", utc_date("2026-01-01"), "m"))
    (hist / INDEX_FILE).unlink()
    table = pq.read_table(path)
    edited = table.set_column(
        table.column_names.index("accuracy"), "accuracy", pq.read_table(path)["tn_rate"]
    )
    pq.write_table(edited.replace_schema_metadata(table.schema.metadata), path)
    with pytest.raises(
        DataError, match=r"c0\.parquet: its rows are not what was written \(48 of 48 rows fail"
    ):
        read_history(hist)


def test_only_verified_rows_are_added(tmp_path):
    folder = run_folder(tmp_path / "r0", seed=0, cells=True)
    path = folder / "results.parquet"
    table = pq.read_table(path)  # a results file edited by hand, its metadata kept
    column = table.column_names.index("accuracy")
    edited = table.set_column(column, "accuracy", table["tn_rate"])
    pq.write_table(edited.replace_schema_metadata(table.schema.metadata), path)
    code = _cli("history", "add", str(path), "--history", str(tmp_path / "hist"), "--commit", "c0")
    assert code == 2
    assert not (tmp_path / "hist").exists()


@pytest.mark.parametrize("commit", ["../up", "a/b", "", "-rf", "x" * 101, "ü"])
def test_a_commit_that_cannot_name_a_file_is_refused(commit):
    with pytest.raises(UsageError, match="--commit"):
        check_commit(commit)


def test_bad_dates_are_refused_and_zones_kept():
    with pytest.raises(UsageError, match="--date: 'yesterday'"):
        utc_date("yesterday")
    assert utc_date("2026-03-01T12:00:00-05:00") == "2026-03-01T17:00:00Z"
    assert utc_date("2026-03-01") == "2026-03-01T00:00:00Z"


@pytest.mark.parametrize("date", ["0001-01-01T00:00:00+01:00", "9999-12-31T23:00:00-05:00"])
def test_a_date_out_of_range_once_utc_is_refused_in_add_and_since(tmp_path, cli, date):
    folder = run_folder(tmp_path / "r0", seed=0)
    hist = str(tmp_path / "hist")
    code, _, err = cli(
        ["history", "add", str(folder), "--history", hist, "--commit", "c0", "--date", date]
    )
    assert code == 2 and err.strip().splitlines()[-1] == (
        f"error: --date: {date!r} falls outside years 1 to 9999 once made UTC"
    )
    assert not (tmp_path / "hist").exists()
    assert cli(["history", "add", str(folder), "--history", hist, "--commit", "c0"])[0] == 0
    code, _, err = cli(["history", "steps", "--history", hist, "--since", date])
    assert code == 2 and err.strip().splitlines() == [
        f"error: --since: {date!r} falls outside years 1 to 9999 once made UTC"
    ]


def test_years_before_1000_are_stored_with_four_digits_and_sort_first(tmp_path):
    assert utc_date("0999-01-01") == "0999-01-01T00:00:00Z"
    assert utc_date("0001-01-01") == "0001-01-01T00:00:00Z"
    hist = tmp_path / "hist"
    for i, day in enumerate(("2026-01-01", "0999-06-01")):
        rows = series_rows(read_results(run_folder(tmp_path / f"r{i}", seed=i, code=f"k{i}")))
        add_run(hist, rows, Run(f"c{i}", utc_date(day), "m"))
    runs = read_history(hist).groupby("run")["commit"].first().tolist()
    assert runs == ["c1", "c0"]  # year 999 is the oldest run
    assert (hist / "runs" / "month=0999-06" / "c1.parquet").is_file()


def test_a_history_that_is_a_file_is_refused(tmp_path, cli):
    folder = run_folder(tmp_path / "r0", seed=0)
    (tmp_path / "file").write_text("not a history")
    for command in (["add", str(folder), "--commit", "c0"], ["steps"], ["page"]):
        code, _, err = cli(["history", *command, "--history", str(tmp_path / "file")])
        assert code == 2 and "is a file" in err, err
    assert (tmp_path / "file").read_text() == "not a history"


def test_a_history_that_is_not_there_is_named(tmp_path):
    with pytest.raises(DataError, match="no history here"):
        read_history(tmp_path / "nothing")
    assert _cli("history", "steps", "--history", str(tmp_path / "nothing")) == 2


def test_rows_the_columns_do_not_tell_apart_are_refused(tmp_path):
    rows = read_results(run_folder(tmp_path / "r0", seed=0))
    twice = pd.concat([rows, rows.assign(key=rows["key"] + "x")], ignore_index=True)
    with pytest.raises(ValueError, match="fall in one series under one seed"):
        series_rows(twice)


def test_a_run_of_two_datasets_names_its_series_apart(tmp_path):
    a = read_results(run_folder(tmp_path / "a", seed=0, dataset_fingerprint="aaaa"))
    b = read_results(run_folder(tmp_path / "b", seed=0, code="code-b", dataset_fingerprint="bbbb"))
    rows = series_rows(pd.concat([a, b], ignore_index=True))
    assert rows["series"].nunique() == 96
    assert rows["series_label"].str.contains("dataset_fingerprint bbbb").sum() == 48


def _as_text(frame: pd.DataFrame) -> pd.DataFrame:
    cats = [c for c in frame if isinstance(frame[c].dtype, pd.CategoricalDtype)]
    return frame.astype({c: "str" for c in cats})


def test_a_categorical_read_holds_the_same_values_and_leaves_the_index(tmp_path):
    hist = tmp_path / "hist"
    for i in range(2):
        rows = series_rows(read_results(run_folder(tmp_path / f"r{i}", seed=i, code=f"k{i}")))
        add_run(hist, rows, Run(f"c{i}", utc_date(f"2026-01-0{i + 1}"), "m"))
    # a run file the index does not hold yet: read beside it, as the index's columns come
    rows = series_rows(read_results(run_folder(tmp_path / "r2", seed=2, code="k2")))
    late = Run("c2", utc_date("2025-12-31"), "m")
    write_atomic(run_table(rows, late), run_path(hist, late))
    before = _files(hist)
    for columns in (None, ["accuracy", "series_label"]):
        plain = read_history(hist, columns)
        coded = read_history(hist, columns, categorical=True)
        assert _files(hist) == before  # proved as read: the index is not rewritten
        texts = [c for c in coded if isinstance(coded[c].dtype, pd.CategoricalDtype)]
        assert "series_label" in texts and "key" not in texts
        pd.testing.assert_frame_equal(_as_text(coded), plain, check_exact=True)
        assert list(coded.groupby("run")["commit"].first()) == ["c2", "c0", "c1"]
    (hist / INDEX_FILE).unlink()  # rebuilt from the run files: their texts coded too
    with pytest.warns(UserWarning, match="rebuilt"):
        coded = read_history(hist, ["accuracy"], categorical=True)
    pd.testing.assert_frame_equal(_as_text(coded), read_history(hist, ["accuracy"]))
