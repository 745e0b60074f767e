"""Stored rows prove themselves: a cell file and results.parquet carry a digest of each row,
checked on every read. A flipped bit or an edit (metadata kept) is refused by name by a report
and computed again by a run; a damaged results.parquet is read from (and rebuilt from) its
cells; a file without digests has its figures range-checked and a line says edits cannot be
detected."""

from __future__ import annotations

import math
import shutil
import warnings
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from slipbench.errors import DataError
from slipbench.store import digests
from slipbench.store.digests import DIGESTS, TABLE
from slipbench.store.results import RESULTS_FILE, ResultsStore, read_results
from slipbench.store.scan import read_cell, scan

FLIPS = 200


@pytest.fixture(scope="module")
def evaluated(unit, tmp_path_factory) -> Path:
    """A results folder of real rows: holweg on one unit, windows of 50 and 100 samples."""
    from slipbench.data.read import read_dataset
    from slipbench.engine import registry
    from slipbench.engine.runner import Run, evaluate

    folder = tmp_path_factory.mktemp("digests") / "run"
    windows = registry.protocols.get("window-size")(windows=[50, 100])
    runs = [Run("holweg", windows, seed=seed) for seed in (0, 1)]
    evaluate(read_dataset(unit), runs, ResultsStore(folder), jobs=0, progress=False)
    return folder


@pytest.fixture
def folder(evaluated, tmp_path) -> Path:
    shutil.copytree(evaluated, tmp_path / "run")
    return tmp_path / "run"


def _same(a: dict, b: dict) -> bool:
    """Two rows say the same (NaN equals NaN; a null is no value)."""
    keys = {k for k, v in a.items() if v is not None} | {k for k, v in b.items() if v is not None}
    return all(
        a.get(k) == b.get(k)
        or (isinstance(a.get(k), float) and math.isnan(a[k]) and math.isnan(b.get(k, 0.0)))
        for k in keys
    )


def _cell(folder: Path) -> Path:
    return sorted((folder / "cells").glob("*.parquet"))[0]


def _rewritten(
    path: Path, column: str, value, keep_metadata: bool = True, key: str | None = None
) -> None:
    """``path`` written again with ``column`` set to ``value`` in the row of ``key`` (default:
    the first), its metadata (the digests) kept or not."""
    table = pq.read_table(path)
    values = table.column(column).to_pylist()
    values[table.column("key").to_pylist().index(key) if key else 0] = value
    edited = table.set_column(
        table.column_names.index(column), column, pa.array(values, table.schema.field(column).type)
    )
    pq.write_table(
        edited.replace_schema_metadata(table.schema.metadata if keep_metadata else None), path
    )


def test_every_stored_row_carries_its_digest(evaluated):
    for path in [*(evaluated / "cells").glob("*.parquet"), evaluated / RESULTS_FILE]:
        assert DIGESTS in pq.read_schema(path).metadata, path
    assert all(read_cell(p, p.stem).proven for p in (evaluated / "cells").glob("*.parquet"))
    assert TABLE in pq.read_schema(evaluated / RESULTS_FILE).metadata


def test_results_parquet_proved_whole_computes_no_row_digest(folder, monkeypatch):
    """Its table digest proves every row at once: what made a read cost 7x a plain one (each
    row's canonical text) is not computed, by a report nor by a run's cached rerun."""
    (folder / RESULTS_FILE).unlink()  # made here: it holds these cell files' versions
    ResultsStore(folder).consolidate()
    expected = read_results(folder).set_index("key").sort_index()

    def refused(row):
        raise AssertionError("a row digest was computed")

    monkeypatch.setattr(digests, "row_digest", refused)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for path in (folder, folder / RESULTS_FILE):
            assert read_results(path).set_index("key").sort_index().equals(expected)
        store = ResultsStore(folder)
        assert set(store.finished()) == set(expected.index)
        store.consolidate()
    # an edit with its metadata kept fails the table digest: its rows are checked one by one
    _rewritten(folder / RESULTS_FILE, "accuracy", 0.01)
    with pytest.raises(AssertionError, match="a row digest was computed"):
        read_results(folder)


def test_a_results_file_of_an_older_slipbench_is_proved_row_by_row(folder):
    """Written before the table digest: its rows' digests prove it, as they did (no line, no
    refusal), and an edit to a row with its metadata kept is still refused."""
    path = folder / RESULTS_FILE
    table = pq.read_table(path)
    old = {k: v for k, v in table.schema.metadata.items() if k != TABLE}
    pq.write_table(table.replace_schema_metadata(old), path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert len(read_results(path)) == len(read_results(folder)) == table.num_rows
    key = table.column("key")[1].as_py()
    _rewritten(path, "accuracy", 0.01, key=key)
    assert TABLE not in pq.read_schema(path).metadata
    with pytest.raises(DataError, match=f"{path}: its rows are not what slipbench wrote: 1 row"):
        read_results(path)
    (folder / "cells" / f"{key}.parquet").unlink()
    with pytest.raises(DataError, match=f"1 row\\(s\\) fail their digest .*e.g. {key}"):
        read_results(folder)


@pytest.mark.slow
def test_no_single_bit_flip_in_a_cell_file_reads_back_changed(folder):
    """200 seeded single-bit flips anywhere in a real cell file: a report either refuses the
    file by name or reads the row unchanged; a run either leaves the cell out (to compute it
    again) or reads it unchanged, and never copies a changed row into results.parquet."""
    path = _cell(folder)
    key, data = path.stem, path.read_bytes()
    good = read_cell(path, key).row
    results = (folder / RESULTS_FILE).read_bytes()
    rng = np.random.default_rng(44)
    outcomes = {"refused": 0, "unchanged": 0}
    for bit in rng.choice(len(data) * 8, FLIPS, replace=False):
        flipped = bytearray(data)
        flipped[bit // 8] ^= 1 << (bit % 8)
        path.write_bytes(bytes(flipped))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                rows = scan(folder, strict=True).rows()
            except DataError as exc:
                assert str(path) in str(exc)
                outcomes["refused"] += 1
            else:
                assert _same(rows[key], good), f"bit {bit} read back changed"
                outcomes["unchanged"] += 1
            run = ResultsStore(folder).finished()
            assert key not in run or _same(run[key], good), f"bit {bit}: a run reused it changed"
            ResultsStore(folder).consolidate()
        kept = {r["key"]: r for r in pq.read_table(folder / RESULTS_FILE).to_pylist()}
        assert key not in kept or _same(kept[key], good), f"bit {bit}: copied changed"
        (folder / RESULTS_FILE).write_bytes(results)
    path.write_bytes(data)
    assert sum(outcomes.values()) == FLIPS and outcomes["refused"] > FLIPS // 4, outcomes


@pytest.mark.slow
def test_no_single_bit_flip_in_results_parquet_reads_back_changed(folder):
    """200 seeded single-bit flips anywhere in a real results.parquet (its table digest, row
    digests, manifest, values, footer): read alone, it is refused by name or reads back
    unchanged; in its folder, a report and a run read every row unchanged (from cells/ where
    the file cannot be used), and a run's rebuild holds only unchanged rows."""
    path = folder / RESULTS_FILE
    data = path.read_bytes()
    good = {r["key"]: r for r in pq.read_table(path).to_pylist()}
    rng = np.random.default_rng(45)
    outcomes = {"refused": 0, "unchanged": 0}
    for bit in rng.choice(len(data) * 8, FLIPS, replace=False):
        flipped = bytearray(data)
        flipped[bit // 8] ^= 1 << (bit % 8)
        path.write_bytes(bytes(flipped))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                alone = read_results(path).to_dict("records")
            except DataError as exc:
                assert str(path) in str(exc)
                outcomes["refused"] += 1
            else:
                assert {r["key"] for r in alone} == set(good), f"bit {bit}: rows lost or added"
                assert all(_same(r, good[r["key"]]) for r in alone), f"bit {bit} read changed"
                outcomes["unchanged"] += 1
            rows = scan(folder, strict=True).rows()
            assert rows.keys() == good.keys() and all(_same(rows[k], good[k]) for k in good)
            run = ResultsStore(folder).finished()
            assert all(_same(run[k], good[k]) for k in run), f"bit {bit}: a run reused it changed"
            ResultsStore(folder).consolidate()
        kept = {r["key"]: r for r in pq.read_table(path).to_pylist()}
        assert all(_same(kept[k], good[k]) for k in kept), f"bit {bit}: rebuilt changed"
    path.write_bytes(data)
    assert sum(outcomes.values()) == FLIPS and outcomes["refused"] > FLIPS // 4, outcomes


@pytest.mark.parametrize("column, value", [("accuracy", 0.99), ("sampling_rate_hz", math.nan)])
def test_an_edit_with_its_metadata_kept_is_refused_by_name(folder, column, value, cli):
    path = _cell(folder)
    _rewritten(path, column, value)
    code, _, err = cli(["report", str(folder)])
    assert code == 2 and f"{path}: its row is not what slipbench wrote" in err
    assert len(err.strip().splitlines()) == 1
    with pytest.warns(UserWarning, match=f"{path.name}: unreadable cell file, its cell will be"):
        assert path.stem not in ResultsStore(folder).finished()  # a run computes it again
    ResultsStore(folder).consolidate()
    # the row results.parquet holds proved itself: it stays as it was computed
    kept = read_results(folder / RESULTS_FILE).set_index("key").loc[path.stem, column]
    assert kept == kept and kept != value


@pytest.mark.slow
def test_a_cached_rerun_computes_an_edited_cell_again_and_never_copies_it(folder, unit, cli):
    path = _cell(folder)
    before = read_cell(path, path.stem).row
    _rewritten(path, "accuracy", 0.01)
    args = ["evaluate", "--detector", "holweg", "--protocol", "window-size", "--dataset", str(unit)]
    args += [
        "--protocol-param",
        "windows=[50,100]",
        "--out",
        str(folder),
        "--jobs",
        "0",
        "--quiet",
        "--repeats",
        "2",
    ]
    code, out, err = cli(args)
    assert code == 0 and f"warning: {path}: unreadable cell file" in err, err
    assert "its row is not what slipbench wrote" in err
    after = read_results(folder).set_index("key").loc[path.stem]
    assert after["accuracy"] == before["accuracy"] != 0.01
    assert read_cell(path, path.stem).proven  # the file is written anew
    code, _, err = cli(args)  # the cell proves itself now (the detector's own warnings may print)
    assert code == 0 and "unreadable" not in err and "not what slipbench wrote" not in err, err


@pytest.mark.parametrize("value", [5.0, -1.0, math.nan])
def test_a_file_without_digests_with_a_figure_out_of_range_is_refused(folder, value, cli):
    stripped = folder.parent / "stripped.parquet"
    shutil.copy(folder / RESULTS_FILE, stripped)
    _rewritten(stripped, "accuracy", value, keep_metadata=False)
    key = pq.read_table(stripped).column("key")[0].as_py()
    for command in (["report", str(stripped)], ["compare", str(stripped), str(folder)]):
        code, _, err = cli(command)
        assert code == 2, (command, err)
        assert f"{stripped}: row 1 (key {key!r}): accuracy {value:g} is not" in err
        assert len(err.strip().splitlines()) == 1


def test_a_file_without_digests_is_read_saying_edits_cannot_be_detected(folder, cli):
    stripped = folder.parent / "stripped.parquet"
    table = pq.read_table(folder / RESULTS_FILE)
    pq.write_table(table.replace_schema_metadata(None), stripped)
    code, out, err = cli(["report", str(stripped)])
    assert code == 0
    said = [line for line in err.splitlines() if "edits to it cannot be detected" in line]
    assert len(said) == 1 and said[0].startswith(f"warning: {stripped}: carries no row digests")
    assert f"{stripped.name}: edits to it cannot be detected" in out  # the report says so too
    code, out, err = cli(["report", str(folder)])
    assert code == 0 and "cannot be detected" not in out + err


def test_a_cell_file_without_digest_is_read_by_a_report_and_not_reused_by_a_run(folder):
    path = _cell(folder)
    table = pq.read_table(path)
    pq.write_table(table.replace_schema_metadata(None), path)  # another tool wrote it
    with pytest.warns(UserWarning, match=r"1 file\(s\) carry no digests .* cannot be detected"):
        rows = read_results(folder)
    assert len(rows) == 4 and rows.attrs["unproven"] == [str(path)]
    with pytest.warns(UserWarning, match=f"{path.name}: unreadable .*it carries no digest"):
        assert path.stem not in ResultsStore(folder).finished()


DAMAGES = {
    "random bytes": lambda p: p.write_bytes(np.random.default_rng(0).bytes(3000)),
    "truncated": lambda p: p.write_bytes(p.read_bytes()[:-40]),
    "its digests not JSON": lambda p: pq.write_table(
        pq.read_table(p).replace_schema_metadata({DIGESTS: b"{not json"}), p
    ),
    "a key twice": lambda p: pq.write_table(
        pa.concat_tables([pq.read_table(p), pq.read_table(p).slice(0, 1)]), p
    ),
    "text not UTF-8": lambda p: pq.write_table(_not_utf8(pq.read_table(p), "detector", 2), p),
}


def _not_utf8(table: pa.Table, column: str, row: int) -> pa.Table:
    values = [v.encode() for v in table.column(column).to_pylist()]
    values[row] = values[row][:2] + b"\xff" + values[row][2:]
    broken = pa.array(values, pa.binary()).view(pa.string())
    return table.set_column(table.column_names.index(column), column, broken)


@pytest.mark.parametrize("damage", list(DAMAGES))
def test_a_damaged_results_file_is_read_and_rebuilt_from_cells(folder, damage, cli):
    whole = read_results(folder).set_index("key").sort_index()
    DAMAGES[damage](folder / RESULTS_FILE)
    code, out, err = cli(["report", str(folder)])
    assert code == 0 and f"warning: {folder / RESULTS_FILE}: " in err, err
    assert "its rows are read from the cell files" in err and "Traceback" not in err
    with pytest.warns(UserWarning, match="read from the cell files .*a run rebuilds it"):
        ResultsStore(folder).finished()
    ResultsStore(folder).consolidate()  # what a run does at its end
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        again = read_results(folder / RESULTS_FILE).set_index("key").sort_index()
    assert again.equals(whole)


def test_text_not_utf8_in_a_results_file_alone_names_column_and_row(folder, cli):
    alone = folder.parent / "alone.parquet"
    table = pq.read_table(folder / RESULTS_FILE)
    pq.write_table(_not_utf8(table, "detector", 2).replace_schema_metadata(None), alone)
    key = table.column("key")[2].as_py()
    for command in (["report", str(alone)], ["compare", str(alone), str(alone)]):
        code, _, err = cli(command)
        assert code == 2 and "Traceback" not in err
        assert f"{alone}: column 'detector', row 3 of 4 (key {key!r}): its text is not" in err


def test_a_row_of_results_parquet_that_fails_its_digest_is_read_from_its_cell(folder):
    table = pq.read_table(folder / RESULTS_FILE)
    key = table.column("key")[0].as_py()
    _rewritten(folder / RESULTS_FILE, "accuracy", 0.01)  # its digests kept
    rows = read_results(folder).set_index("key")
    assert (
        rows.loc[key, "accuracy"]
        == read_cell(folder / "cells" / f"{key}.parquet", key).row["accuracy"]
    )
    ResultsStore(folder).consolidate()  # rebuilt: the row proved by its cell
    assert read_results(folder / RESULTS_FILE).set_index("key").loc[key, "accuracy"] != 0.01
    # without its cell file, a report refuses the row and a run leaves it out
    _rewritten(folder / RESULTS_FILE, "accuracy", 0.01, key=key)
    (folder / "cells" / f"{key}.parquet").unlink()
    with pytest.raises(DataError, match=f"1 row\\(s\\) fail their digest .*e.g. {key}"):
        read_results(folder)
    with pytest.warns(UserWarning, match="fail their digest and no cell file holds them"):
        assert key not in ResultsStore(folder).finished()


def test_text_not_utf8_in_a_predictions_file_names_column_and_row(folder):
    from slipbench.store.results import read_predictions

    path = next((folder / "predictions").glob("*.parquet"))
    pq.write_table(_not_utf8(pq.read_table(path), "recording_id", 4), path)
    with pytest.raises(DataError, match=f"{path}: column 'recording_id', row 5 of "):
        read_predictions(folder, path.stem)


def test_damaged_pandas_metadata_is_not_needed(folder, cli):
    """pandas writes notes on its table in the metadata; a flipped bit there made every
    conversion to a frame fail (exit 70): flat result rows need none of it."""
    written = folder.parent / "by-pandas.parquet"
    read_results(folder / RESULTS_FILE).to_parquet(written)
    table = pq.read_table(written)
    notes = dict(table.schema.metadata)
    notes[b"pandas"] = notes[b"pandas"].replace(b'"columns"', b'"colu\xffns"', 1)
    pq.write_table(table.replace_schema_metadata(notes), written)
    code, out, err = cli(["report", str(written)])
    assert code == 0 and "edits to it cannot be detected" in err and "Traceback" not in err
