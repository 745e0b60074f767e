"""The history proves itself: run files carry row digests, the index a digest of each column and
of its manifest. A flipped bit or an edit in the index rebuilds it from the run files with one
line; a damaged run file, or one copied under another name or month, is refused by name; rows
that entered without digests are marked unproven, and steps and the site show the mark."""

from __future__ import annotations

import json
import shutil
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from historygen import run_folder
from parquetfaults import name_not_utf8

from slipbench.app.cli import main
from slipbench.errors import DataError
from slipbench.store.history import INDEX_FILE, _json_digest, read_history

FAST_FLIPS = 30
SLOW_FLIPS = 300


def _cli(*args: str) -> int:
    with pytest.raises(SystemExit) as exit_:
        main(list(args))
        raise SystemExit(0)
    return int(exit_.value.code or 0)


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> Path:
    """A history of three runs (c1's results carry no digests: unproven), its index written."""
    root = tmp_path_factory.mktemp("proofs")
    for i in range(3):
        folder = run_folder(root / f"r{i}", seed=i, code=f"k{i}", cells=i != 1)
        day = f"2026-01-{i + 1:02d}"
        assert (
            _cli(
                "history",
                "add",
                str(folder),
                "--history",
                str(root / "h"),
                "--commit",
                f"c{i}",
                "--date",
                day,
            )
            == 0
        )
    return root / "h"


@pytest.fixture
def hist(built, tmp_path) -> Path:
    shutil.copytree(built, tmp_path / "h")
    return tmp_path / "h"


def _run(hist: Path, commit: str = "c0") -> Path:
    return next(hist.glob(f"runs/month=*/{commit}.parquet"))


def _read(hist: Path) -> tuple[pd.DataFrame | None, list[str], str]:
    """What a reader gets: the rows (None where refused), its warnings, the refusal."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            frame = read_history(hist)
        except DataError as exc:
            return None, [str(w.message) for w in caught], str(exc)
    return frame, [str(w.message) for w in caught], ""


def _flips(path: Path, hist: Path, good: pd.DataFrame, n: int, seed: int) -> dict[str, int]:
    """``n`` seeded single-bit flips of ``path``, each read back: refused naming a run file,
    rebuilt with one line, or read unchanged; never changed."""
    data, index = path.read_bytes(), (hist / INDEX_FILE).read_bytes()
    rng = np.random.default_rng(seed)
    outcomes = {"refused": 0, "rebuilt": 0, "unchanged": 0}
    for bit in rng.choice(len(data) * 8, n, replace=False):
        flipped = bytearray(data)
        flipped[bit // 8] ^= 1 << (bit % 8)
        path.write_bytes(bytes(flipped))
        if path.name != INDEX_FILE:
            (hist / INDEX_FILE).unlink()  # the run file must be read, not vouched for
        frame, said, refused = _read(hist)
        if frame is None:
            assert str(path) in refused, f"bit {bit}: {refused}"
            outcomes["refused"] += 1
        else:
            pd.testing.assert_frame_equal(frame, good, obj=f"bit {bit}")
            rebuilt = [w for w in said if "rebuilt from the 3 run files" in w]
            if path.name == INDEX_FILE and rebuilt:
                outcomes["rebuilt"] += 1
            else:
                outcomes["unchanged"] += 1
            assert len(said) <= 1, said
        path.write_bytes(data)
        (hist / INDEX_FILE).write_bytes(index)
    return outcomes


@pytest.mark.parametrize("target", ["index", "run"])
def test_no_bit_flip_in_the_history_reads_back_changed(hist, target):
    good = read_history(hist)
    path = hist / INDEX_FILE if target == "index" else _run(hist)
    outcomes = _flips(path, hist, good, FAST_FLIPS, seed=52)
    assert sum(outcomes.values()) == FAST_FLIPS
    caught = outcomes["rebuilt"] if target == "index" else outcomes["refused"]
    assert caught > FAST_FLIPS // 2, outcomes


@pytest.mark.slow
@pytest.mark.parametrize("target", ["index", "run"])
def test_300_bit_flips_in_the_history_never_read_back_changed(hist, target):
    good = read_history(hist)
    path = hist / INDEX_FILE if target == "index" else _run(hist, "c2")
    outcomes = _flips(path, hist, good, SLOW_FLIPS, seed=5252)
    assert sum(outcomes.values()) == SLOW_FLIPS, outcomes


def test_a_run_file_flipped_under_an_intact_index_changes_nothing_shown(hist):
    """The proved index holds the run at its size: the run file is not read, the numbers are
    the index's; once the index is rebuilt the damaged file is refused by name."""
    good = read_history(hist)
    path = _run(hist)
    data = bytearray(path.read_bytes())
    at = data.index(b"c0") + 1
    data[at] ^= 1  # a bit of the commit's text in the data pages
    path.write_bytes(bytes(data))
    pd.testing.assert_frame_equal(read_history(hist), good)
    (hist / INDEX_FILE).unlink()
    frame, _, refused = _read(hist)
    assert frame is None and str(path) in refused


def _edit_index(hist: Path, column: str, value) -> None:
    path = hist / INDEX_FILE
    table = pq.read_table(path)
    edited = table.set_column(
        table.column_names.index(column),
        column,
        pa.array([value] * table.num_rows, table.schema.field(column).type),
    )
    pq.write_table(edited.replace_schema_metadata(table.schema.metadata), path)


def test_a_hand_edited_index_is_rebuilt_with_one_line(hist, capsys):
    good = read_history(hist)
    _edit_index(hist, "accuracy", 0.10)
    assert _cli("history", "steps", "--history", str(hist), "--json") == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"warning: {hist / INDEX_FILE} holds values of 'accuracy' that are not those it was "
        "written with: rebuilt from the 3 run files"
    ]
    pd.testing.assert_frame_equal(read_history(hist), good)
    assert not _read(hist)[1]  # the rebuilt index was written: no line the next time


@pytest.mark.parametrize(
    "damage, said",
    [
        ("missing", "is missing"),
        ("metadata not a mapping", "is not of this slipbench's format"),
        ("a column of another type", "columns of other names or types"),
        ("text not UTF-8", "is damaged"),
        ("a run file dropped from the manifest", "manifest that is not the one it was written"),
        ("a forged manifest (its digest made again)", "holds other runs than its manifest says"),
        ("a run file gone", "disagrees with the run files"),
    ],
)
def test_a_damaged_index_is_rebuilt_from_the_run_files(hist, damage, said):
    good = read_history(hist)
    path = hist / INDEX_FILE
    table = pq.read_table(path)
    meta = json.loads(table.schema.metadata[b"slipbench.history"])
    if damage == "missing":
        path.unlink()
    elif damage == "metadata not a mapping":
        pq.write_table(table.replace_schema_metadata({b"slipbench.history": b"[1, 2]"}), path)
    elif damage == "a column of another type":
        seed = table.column_names.index("seed")
        pq.write_table(table.set_column(seed, "seed", table["seed"].cast(pa.float64())), path)
    elif damage == "text not UTF-8":
        path.write_bytes(name_not_utf8(path.read_bytes(), "series_label"))
    elif damage.startswith(("a run file dropped", "a forged")):
        # the index still holds the dropped file's rows: read with the file again, 48 rows twice
        del meta["files"][next(iter(meta["files"]))]
        if damage.startswith("a forged"):
            meta["files"]["runs/month=2026-01/c1.parquet"]["rows"] += 48
            meta["digest"] = _json_digest({k: v for k, v in meta.items() if k != "digest"})
        pq.write_table(
            table.replace_schema_metadata({b"slipbench.history": json.dumps(meta)}), path
        )
    else:
        gone = _run(hist, "c1")
        gone.unlink()
        good = good[good["commit"] != "c1"].reset_index(drop=True)
        good["run"] = good["run"].map({0: 0, 2: 1})
    frame, lines, _ = _read(hist)
    runs = 2 if damage == "a run file gone" else 3
    assert (
        len(lines) == 1 and said in lines[0] and f"rebuilt from the {runs} run files" in lines[0]
    ), lines
    pd.testing.assert_frame_equal(frame, good)


def test_a_run_file_copied_under_another_name_or_month_is_refused_by_name(hist, cli):
    source = _run(hist, "c0")
    for copy in (source.with_name("c9.parquet"), hist / "runs" / "month=2026-02" / "c0.parquet"):
        copy.parent.mkdir(exist_ok=True)
        shutil.copy(source, copy)
        frame, _, refused = _read(hist)
        assert (
            frame is None and refused.startswith(f"{copy}: ") and "move it out of runs/" in refused
        )
        code, _, err = cli(["history", "steps", "--history", str(hist)])
        assert code == 2 and err.strip().splitlines() == [f"error: {refused}"]
        copy.unlink()
    assert len(read_history(hist)) == 3 * 48


def _value_not_utf8(path: Path, column: str) -> None:
    """``path`` written again with the first value of ``column`` not UTF-8 (metadata kept)."""
    table = pq.read_table(path)
    raw = pa.array([b"\xff" + v.encode() for v in table[column].to_pylist()], pa.binary())
    text = pa.Array.from_buffers(pa.string(), len(raw), raw.buffers())
    at = table.column_names.index(column)
    pq.write_table(table.set_column(at, column, text), path)


@pytest.mark.parametrize(
    "where, said",
    [
        ("name", "not valid UTF-8"),
        ("value", "not valid UTF-8"),
        ("type", "holds double, not int64"),
    ],
)
def test_a_damaged_run_file_is_refused_by_name(hist, cli, where, said):
    path = _run(hist, "c2")
    if where == "name":
        path.write_bytes(name_not_utf8(path.read_bytes(), "series_label"))
    elif where == "value":
        _value_not_utf8(path, "series_label")
    else:
        table = pq.read_table(path)
        at = table.column_names.index("seed")
        pq.write_table(table.set_column(at, "seed", table["seed"].cast(pa.float64())), path)
    (hist / INDEX_FILE).unlink()
    code, _, err = cli(["history", "steps", "--history", str(hist)])
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"error: {path}: column ") and said in err, err


def test_a_run_file_of_another_format_is_refused_saying_so(hist, cli):
    path = _run(hist, "c0")
    table = pq.read_table(path)
    meta = dict(table.schema.metadata)
    meta[b"slipbench.history"] = json.dumps({"format": 1, "commit": "c0", "digest": "0"})
    pq.write_table(table.replace_schema_metadata(meta), path)
    (hist / INDEX_FILE).unlink()
    code, _, err = cli(["history", "steps", "--history", str(hist)])
    assert code == 2 and err.strip().splitlines() == [
        f"error: {path}: a history run file of format 1; this slipbench reads format 2 (add the "
        "run again with this version)"
    ]


def test_an_index_value_not_utf8_is_rebuilt(hist, cli):
    good = read_history(hist)
    _value_not_utf8(hist / INDEX_FILE, "series_label")
    code, _, err = cli(["history", "steps", "--history", str(hist)])
    assert code == 0 and err.startswith(
        f"warning: {hist / INDEX_FILE} holds values of 'series_label'"
    )
    pd.testing.assert_frame_equal(read_history(hist), good)


def test_rows_that_entered_unproven_are_marked_in_steps_and_site(hist, tmp_path, cli):
    frame = read_history(hist)
    assert frame.groupby("commit")["proven"].all().to_dict() == {
        "c0": True,
        "c1": False,
        "c2": True,
    }
    text = cli(["history", "steps", "--history", str(hist)])[1]
    assert "1 run holds rows that entered unproven" in text and "c1 (48 rows)" in text
    steps = json.loads(cli(["history", "steps", "--history", str(hist), "--json"])[1])
    assert steps["unproven_runs"] == ["c1"]
    site = tmp_path / "site"
    assert cli(["history", "page", "--history", str(hist), "--out", str(site)])[0] == 0
    series = (site / "series.html").read_text()
    assert '["c1 (unproven)","2026-01-02T00:00:00Z"]' in series
    assert "1 run holds rows that entered unproven (c1)" in (site / "index.html").read_text()
