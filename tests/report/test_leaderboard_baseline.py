"""The leaderboard's line to beat: each entrant's paired change from the reference."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
from resultgen import fake_rows, predictions_pair

from slipbench.report.document import build_report, render
from slipbench.report.leaderboard import NO_BASELINE, leaderboard_tables, versus_baseline
from slipbench.stats.factors import named_entrants
from slipbench.stats.leaderboard import leaderboard
from slipbench.stats.pairs import paired_change

NUMBER = r"([+-]\d+\.\d)"


def board_tables(rows: pd.DataFrame, folders=()) -> list:
    tables = leaderboard_tables(leaderboard(rows))
    versus_baseline(tables, rows, folders)
    return tables


def column(table) -> dict[str, str]:
    assert table.columns[-1] == "vs baseline (features)"
    return {line[0]: cells[-1] for line, cells in zip(table.rows, table.cells)}


def assert_is(text: str, change: dict) -> None:
    """``text`` shows ``change``'s mean and interval, in points to one decimal."""
    found = re.fullmatch(rf"{NUMBER} \[{NUMBER}, {NUMBER}\]", text)
    assert found, text
    shown = np.array([float(x) for x in found.groups()])
    expected = 100 * np.array([change["d"], change["lo"], change["hi"]])
    assert np.all(np.abs(shown - expected) <= 0.05 + 1e-9), (shown, expected)
    assert change["lo"] < change["d"] < change["hi"]


def test_joint_bootstrap_change_from_predictions(tmp_path):
    base, cand = predictions_pair(tmp_path, n_cells=4, trials=12, flip=0.25)
    ref = pd.read_parquet(base / "results.parquet").assign(
        detector="features", detector_reference=True
    )
    other = pd.read_parquet(cand / "results.parquet")
    rows = named_entrants(pd.concat([ref, other], ignore_index=True))
    texts = column(board_tables(rows, (base, cand))[1])
    assert texts["features"] == "reference"
    change = paired_change(ref, other, (base, cand))
    assert change["n_cells"] == 4 and change["method"].startswith("joint cluster")
    assert_is(texts["holweg"], change)
    assert change["hi"] < 0  # a quarter of the trials flipped wrong: a clear drop


def test_change_from_rows_per_entrant_and_one_class_cells_left_out():
    ref = fake_rows("window-size", "features").head(12)
    holweg = fake_rows("window-size", "holweg", shift=0.03).head(12)
    lstm = fake_rows("window-size", "lstm").head(12)
    # a one-class test set both ran, which the leaderboard does not rank: the change leaves it
    # out too (with it, holweg's change would rise by 0.8 / 13, about 6 points)
    lone = pd.concat([ref.head(1), holweg.head(1)]).assign(cell='{"one": 1}', key=["l0", "l1"])
    lone = lone.assign(accuracy=[0.2, 1.0], constant_slip_accuracy=1.0)
    rows = named_entrants(pd.concat([ref, holweg, lstm, lone], ignore_index=True))
    both = [rows[rows["detector"] == d] for d in ("features", "holweg")]
    assert paired_change(*both)["n_cells"] == len(ref) + 1  # unfiltered, the pairing takes it
    tables = board_tables(rows)
    texts = column(tables[1])
    assert texts["features"] == "reference"
    for name, mine in (("holweg", holweg), ("lstm", lstm)):
        change = paired_change(ref, mine)
        assert change["n_cells"] == len(ref) and change["method"].startswith("from the rows")
        assert_is(texts[name], change)
    assert NO_BASELINE not in tables[0].notes
    assert any("vs baseline (features): each detector's" in n for n in tables[1].notes)


def test_cells_with_a_seed_stored_twice_are_left_out_and_said():
    ref = fake_rows("window-size", "features").head(6)
    holweg = fake_rows("window-size", "holweg", shift=0.03).head(6)
    again = ref.head(2).assign(key=ref["key"].head(2) + "-rerun")  # a second run of two cells
    rows = named_entrants(pd.concat([ref, again, holweg], ignore_index=True))
    tables = board_tables(rows)
    change = paired_change(pd.concat([ref, again]), holweg)
    assert change["n_cells"] == 4 and change["n_skipped"] == 2
    assert_is(column(tables[1])["holweg"], change)
    assert any(n.startswith("vs baseline: 2 shared cells were left out") for n in tables[1].notes)
    every = [ref, ref.assign(key=ref["key"] + "-rerun"), holweg]
    every = named_entrants(pd.concat(every, ignore_index=True))
    assert column(board_tables(every)[1])["holweg"] == "a seed stored twice"


def test_without_the_reference_no_column_and_one_line_why():
    rows = pd.concat(
        [fake_rows("window-size", d).head(12) for d in ("lstm", "holweg")], ignore_index=True
    )
    tables = board_tables(named_entrants(rows))
    assert all("vs baseline" not in " ".join(t.columns) for t in tables)
    assert [n for t in tables for n in t.notes].count(NO_BASELINE) == 1


def test_the_leaderboard_report_shows_the_column():
    rows = pd.concat(
        [
            fake_rows("window-size", d, shift=s).head(12)
            for d, s in (("features", 0), ("holweg", 0.02))
        ],
        ignore_index=True,
    )
    text = render(build_report(rows, leaderboard_only=True), "md", False, {})
    assert "vs baseline (features)" in text
    assert re.search(r"\|\s+features \|.*\|\s+reference \|", text)
