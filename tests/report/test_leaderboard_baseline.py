"""The leaderboard's line to beat: each entrant's paired change from the reference."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
from resultgen import fake_rows, predictions_pair

from slipbench.report.blocks import Table
from slipbench.report.document import build_report, render
from slipbench.report.leaderboard import (
    NO_BASELINE,
    leaderboard_tables,
    versus_baseline,
    versus_column,
)
from slipbench.stats.contrast import ONE_SEED, Contrast, pair_seeds, paired_change
from slipbench.stats.factors import named_entrants
from slipbench.stats.leaderboard import leaderboard

NUMBER = r"([+-]\d+\.\d)"


def board_tables(rows: pd.DataFrame, folders=()) -> list:
    tables = leaderboard_tables(leaderboard(rows))
    versus_baseline(tables, rows, folders)
    return tables


def column(table) -> dict[str, str]:
    assert table.columns[-1] == "vs baseline (features)"
    return {line[0]: cells[-1] for line, cells in zip(table.rows, table.cells)}


def assert_is(text: str, change: Contrast) -> None:
    """``text`` shows ``change``'s mean and interval, in points to one decimal."""
    found = re.fullmatch(rf"{NUMBER} \[{NUMBER}, {NUMBER}\]", text)
    assert found, text
    shown = np.array([float(x) for x in found.groups()])
    expected = 100 * np.array([change.estimate, change.lo, change.hi])
    assert np.all(np.abs(shown - expected) <= 0.05 + 1e-9), (shown, expected)
    assert change.lo < change.estimate < change.hi


def change_of(base: pd.DataFrame, cand: pd.DataFrame, folders=()) -> Contrast:
    return paired_change(pair_seeds(base, cand), folders=folders)


def test_joint_bootstrap_change_from_predictions(tmp_path):
    base, cand = predictions_pair(tmp_path, n_cells=4, trials=12, flip=0.25)
    ref = pd.read_parquet(base / "results.parquet").assign(
        detector="features", detector_reference=True
    )
    other = pd.read_parquet(cand / "results.parquet")
    rows = named_entrants(pd.concat([ref, other], ignore_index=True))
    texts = column(board_tables(rows, (base, cand))[1])
    assert texts["features"] == "reference"
    change = change_of(ref, other, (base, cand))
    assert change.n_cells == 4 and change.method.startswith("joint cluster")
    # these cells rest on few test trials (12 a class, some of them one class only): marked
    assert ref["low_n"].any() and texts["holweg"].endswith("†")
    assert_is(texts["holweg"].removesuffix("†"), change)
    assert change.hi < 0  # a quarter of the trials flipped wrong: a clear drop


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
    assert change_of(*both).n_cells == len(ref) + 1  # unfiltered, the pairing takes it
    tables = board_tables(rows)
    texts = column(tables[1])
    assert texts["features"] == "reference"
    for name, mine in (("holweg", holweg), ("lstm", lstm)):
        change = change_of(ref, mine)
        assert change.n_cells == len(ref) and change.method.startswith("from the rows")
        assert_is(texts[name], change)
    assert NO_BASELINE not in tables[0].notes
    assert any("vs baseline (features): each detector's" in n for n in tables[1].notes)
    # one seed each: the interval is shown, and said to decide nothing
    assert change.missing == ONE_SEED and change.state == "undecided"
    assert any(
        "on one seed: the interval holds the test trials' noise only" in n for n in tables[1].notes
    )


def test_cells_with_a_seed_stored_twice_are_left_out_and_said():
    ref = fake_rows("window-size", "features").head(6)
    holweg = fake_rows("window-size", "holweg", shift=0.03).head(6)
    again = ref.head(2).assign(key=ref["key"].head(2) + "-rerun")  # a second run of two cells
    rows = named_entrants(pd.concat([ref, again, holweg], ignore_index=True))
    tables = board_tables(rows)
    change = change_of(pd.concat([ref, again]), holweg)
    assert change.n_cells == 4
    assert change.left_out == ("2 cells holding a seed stored twice on a side",)
    assert_is(column(tables[1])["holweg"], change)
    said = (
        "vs baseline (features), holweg: left out: 2 cells holding a seed stored twice on a side."
    )
    assert said in tables[1].notes
    every = [ref, ref.assign(key=ref["key"] + "-rerun"), holweg]
    every = named_entrants(pd.concat(every, ignore_index=True))
    assert column(board_tables(every)[1])["holweg"] == "no cell and seed both finished"


def test_the_change_is_paired_seed_by_seed_and_names_the_seeds_left_out():
    """The issue's repro: the reference at seeds 0-4, holweg at seed 0. The change is holweg's
    minus the reference's at seed 0, not minus the reference's 5-seed mean, and seeds 1-4 are
    named as left out."""
    ref = fake_rows("window-size", "features", seeds=(0, 1, 2, 3, 4)).head(60)
    holweg = fake_rows("window-size", "holweg", shift=0.03).head(12)
    cells = holweg["cell"].nunique()
    ref = ref[ref["cell"].isin(holweg["cell"])]
    change = change_of(ref, holweg)
    at_0 = ref[ref["seed"] == 0].set_index("cell")["accuracy"]
    paired = (holweg.set_index("cell")["accuracy"] - at_0).mean()
    unpaired = holweg["accuracy"].mean() - ref["accuracy"].mean()
    assert abs(change.estimate - paired) < 1e-12 and abs(paired - unpaired) > 0.005
    assert change.seeds == (0,) and change.n_cells == cells
    assert change.left_out == (f"seeds 1, 2, 3, 4 of {cells} cells: BASE only",)
    rows = named_entrants(pd.concat([ref, holweg], ignore_index=True))
    tables = board_tables(rows)
    assert_is(column(tables[1])["holweg"], change)
    named = (
        "vs baseline (features), holweg: left out: "
        f"seeds 1, 2, 3, 4 of {cells} cells: the reference only."
    )
    assert named in tables[1].notes


def test_streaming_rows_are_compared_on_their_detection_rate():
    """Streaming cells hold no accuracy: their line to beat is the detection rate's change, not
    "no shared cell"."""
    ref = fake_rows("window-size", "features").head(6)
    rows = []
    for detector, shift in (("features", 0.0), ("holweg", 0.05)):
        part = ref.assign(detector=detector, key=ref["key"] + detector)
        part = part.assign(
            detection_rate=part["accuracy"] + shift,
            detection_rate_lo=part["accuracy_lo"] + shift,
            detection_rate_hi=part["accuracy_hi"] + shift,
            stream_s=1.0,
        )
        rows.append(
            part.drop(columns=[c for c in part if c.startswith(("accuracy", "tp_", "tn_"))])
        )
    rows = named_entrants(pd.concat(rows, ignore_index=True))
    change = paired_change(
        pair_seeds(
            *(rows[rows["detector"] == d] for d in ("features", "holweg")), "detection_rate"
        ),
        "detection_rate",
    )
    assert abs(change.estimate - 0.05) < 1e-12 and change.n_cells == 6
    table = Table("t", ["Detector"], "", ["x"], [("features",), ("holweg",)], [["1"], ["2"]], "")
    versus_column(table, rows, ["features"])
    assert table.cells[1][-1].startswith("+5.0 [")
    assert "detection rate minus the reference's" in table.notes[0]


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


def test_a_change_over_low_n_cells_carries_the_mark():
    ref = fake_rows("window-size", "features").head(6).assign(low_n=False)
    holweg = fake_rows("window-size", "holweg", shift=0.03).head(6).assign(low_n=False)
    holweg.loc[holweg.index[0], "low_n"] = True
    table = column(board_tables(named_entrants(pd.concat([ref, holweg], ignore_index=True)))[1])
    assert table["holweg"].endswith("†") and table["features"] == "reference"


def test_the_metric_governs_the_line_to_beat():
    """``report --metric balanced_accuracy``: the 'vs baseline' column is the change in balanced
    accuracy (here +6 points where accuracy moved +2), named in its header and note, in the
    leaderboard's means table and in every detector's side-by-side table."""
    parts = []
    for d, acc, bal in (("features", 0.0, 0.0), ("holweg", 0.02, 0.06)):
        part = fake_rows("window-size", d).head(12)
        level = fake_rows("window-size", "features")["accuracy"].head(12)
        for col in ("accuracy", "accuracy_lo", "accuracy_hi"):
            part[col] = fake_rows("window-size", "features")[col].head(12) + acc
        part["balanced_accuracy"] = level + bal
        part["balanced_accuracy_lo"] = part["balanced_accuracy"] - 0.02
        part["balanced_accuracy_hi"] = part["balanced_accuracy"] + 0.02
        parts.append(part)
    rows = named_entrants(pd.concat(parts, ignore_index=True))
    for metric, header, shown in (
        ("accuracy", "vs baseline (features)", "+2.0 "),
        ("balanced_accuracy", "vs baseline, balanced accuracy (features)", "+6.0 "),
    ):
        text = render(build_report(rows, leaderboard_only=True, metric=metric), "md", False, {})
        assert header in text
        line = next(ln for ln in text.splitlines() if header in ln)
        at = [c.strip() for c in line.split("|")].index(header)
        means = text[text.index(line) :].splitlines()
        holweg = next(ln for ln in means if ln.split("|")[1].strip() == "holweg")
        assert holweg.split("|")[at].strip().startswith(shown), holweg
        tables = leaderboard_tables(leaderboard(rows, metric))
        versus_baseline(tables, rows, metric=metric)
        assert tables[1].columns[-1] == header


def test_a_change_without_an_estimable_interval_says_why_beside_it():
    """The [-100, +100] of a change whose cells' intervals are not estimable is said, with the
    cells, under the column: never a bare whole-range interval."""
    from slipbench.report.versus import add_versus

    lacks = (
        "the interval of 1 cell is not estimable (a class holds a single test trial; the row "
        "shows the figure's whole range): window-size window=50"
    )
    change = Contrast(-0.005, -1.0, 1.0, missing=lacks, n_cells=4, seeds=(0, 1))
    table = Table("t", ["Detector"], "", ["x"], [("features",), ("holweg",)], [["1"], ["2"]], "")
    add_versus(table, [None, (change, 0)], "features", "accuracy")
    assert table.cells[1][-1] == "-0.5 [-100.0, +100.0]"
    assert f"vs baseline (features), holweg: undecided: {lacks}." in table.notes
