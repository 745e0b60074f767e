"""What a report says of the data behind it (issue 33): rows tested on another dataset name the
unit tested and what it was trained as; cells tested on one class get a table of their own and
no rank; channels cells on the simulation carry a caution, read from the dataset's source. And
one real run of two normalizations, transferred onto slip-only recordings, for the plumbing."""

from __future__ import annotations

import json

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from datagen import subset
from resultgen import fake_rows

from slipbench.data.read import read_dataset
from slipbench.data.transfer import combine
from slipbench.data.write import write_dataset
from slipbench.engine.plan import Run
from slipbench.engine.runner import evaluate
from slipbench.protocols.window_size import WindowSize
from slipbench.report.blocks import Table
from slipbench.report.document import build_report, protocol_tables, render
from slipbench.report.notes import SIMULATED, SIMULATION_NOTE
from slipbench.report.outline import as_tested
from slipbench.report.presentation import shown_protocol
from slipbench.report.provenance import _where, header_tables, on_simulation
from slipbench.store.results import ResultsStore, read_results


def _rows(**columns) -> pd.DataFrame:
    rows = fake_rows("window-size", "holweg")
    rows = rows[rows["sensor_type"].eq("Nano17") & rows["window"].isin([50, 200])]
    return rows.assign(**columns).reset_index(drop=True)


def test_transfer_rows_name_the_unit_tested_and_what_it_was_trained_as():
    rows = _rows(sensor_map=json.dumps({"Vib:probe": "Nano17:index", "Vib:tip": "Nano17:middle"}))
    shown = as_tested(rows)
    index = shown[rows["sensor_instance"].eq("index")]
    assert set(index["sensor_type"]) == {"Vib"}
    assert set(index["sensor_instance"]) == {"probe (trained as Nano17 index)"}
    little = shown[rows["sensor_instance"].eq("little")]  # the map tested nothing as it
    assert set(little["sensor_type"]) == {"Nano17"} and set(little["sensor_instance"]) == {"little"}
    (_, table), *_ = protocol_tables(
        shown, shown_protocol(WindowSize(), "window-size"), "window-size", "holweg"
    )
    assert ("Vib", "probe (trained as Nano17 index)") in table.rows
    assert any(n.startswith("Trained on one dataset, tested on another") for n in table.notes)
    # two test units tested as one training unit: both named
    two = as_tested(_rows(sensor_map=json.dumps({"A:x": "Nano17:index", "A:y": "Nano17:index"})))
    assert "x + y (trained as Nano17 index)" in set(two["sensor_instance"])


def test_smallest_test_set_names_the_unit_tested_not_the_one_trained():
    # issue 54: a transfer row's cell is keyed by the training unit; the header named it
    rows = _rows(sensor_map=json.dumps({"Vib:probe": "Nano17:index"}))
    rows["n_test_trials"] = 20
    at = rows.index[rows["sensor_instance"].eq("index")][0]
    rows.loc[at, "n_test_trials"] = 3
    run = header_tables(rows)[0]
    (line,) = [c[0] for r, c in zip(run.rows, run.cells) if r[0] == "Smallest test set"]
    assert "3 test trials" in line and "Vib:probe (trained as Nano17 index)" in line
    # a cross-instance cell across datasets: its test instance is the one renamed
    cross = _rows(sensor_map=json.dumps({"Vib:tip": "Nano17:middle"}))
    cross["cell"] = json.dumps(
        {"sensor_type": "Nano17", "train_instance": "index", "test_instance": "middle"}
    )
    assert _where(cross.iloc[0]).endswith("Nano17 Index → Vib:tip (trained as Nano17 middle)")
    # within one dataset nothing is renamed
    assert _where(_rows().iloc[0]) == _where(_rows(sensor_map="").iloc[0])


def _dataset(folder, source: str):
    folder.mkdir()
    pq.write_table(pa.table({"source": [source, source]}), folder / "recordings.parquet")
    return str(folder)


def test_channels_cells_on_the_simulation_carry_a_caution(tmp_path):
    # model version 3's force direction gives slip away; version 4's shear without slip does not
    simulated = _dataset(tmp_path / "sim", "slipbench.synth v3 seed=0 scale=0.05")
    recorded = _dataset(tmp_path / "lab", "slipbench.synth v4 seed=0 scale=0.05")
    gone = str(tmp_path / "synth-v3-scale0.05-seed0")  # not here: its folder's name says
    rows = pd.concat(
        [
            _rows(dataset_path=p, input=i)
            for p in (simulated, recorded, gone)
            for i in ("univariate", "channels")
        ],
        ignore_index=True,
    )
    assert on_simulation(rows).tolist() == [True] * (len(rows) // 3) + [False] * (
        len(rows) // 3
    ) + [True] * (len(rows) // 3)
    rows = rows.assign(**{SIMULATED: on_simulation(rows)})

    def notes(part: pd.DataFrame) -> list[str]:
        (_, table), *_ = protocol_tables(
            part, shown_protocol(WindowSize(), "window-size"), "window-size", "holweg"
        )
        return table.notes

    for path, input_, cautioned in (
        (simulated, "channels", True),
        (simulated, "univariate", False),
        (recorded, "channels", False),
        (gone, "channels", True),
    ):
        part = rows[rows["dataset_path"].eq(path) & rows["input"].eq(input_)]
        assert (SIMULATION_NOTE in notes(part)) == cautioned, (path, input_)
    # the leaderboard's mean figures say it too, the report marking the rows itself
    channels = rows[rows["dataset_path"].eq(simulated) & rows["input"].eq("channels")]
    board = build_report(channels.drop(columns=SIMULATED), leaderboard_only=True)
    means = next(t for t in board if isinstance(t, Table) and t.label == "tab:leaderboard-means")
    assert SIMULATION_NOTE in means.notes


def test_one_class_cells_get_their_own_table_and_no_rank():
    lone_rows = _rows(constant_slip_accuracy=1.0, split="datasets")
    text = render(build_report(lone_rows, leaderboard_only=True), "md")
    assert "6 finished cells test on one class only and are not ranked" in text
    # beside a split of both classes, which leads: the table still lists them, by split
    rows = pd.concat([lone_rows, _rows(key=lone_rows["key"] + "-two")], ignore_index=True)
    blocks = build_report(rows, leaderboard_only=True)
    assert "all (6)" in render(blocks, "md")  # the paper split's 6 cells ranked
    lone = next(t for t in blocks if isinstance(t, Table) and t.label == "tab:one-class")
    assert lone.columns[0] == "Class tested" and {c[0] for c in lone.cells} == {"slip"}
    assert {c[3] for c in lone.cells} == {"100.0"} and len(lone.rows) == 3  # three fingers


@pytest.fixture(scope="module")
def transferred(unit, tmp_path_factory):
    """holweg at window 50 trained on a simulated unit and tested on its slip recordings
    alone, with the signal as measured and normalized per unit, into one folder."""
    folder = tmp_path_factory.mktemp("transfer")
    train = read_dataset(unit)
    slip = subset(train, train.recordings["scenario"].eq("slip"))
    test = read_dataset(
        write_dataset(folder / "slip", slip.recordings, slip.samples, slip.slip_labels)
    )
    both = combine(train, test)
    store = ResultsStore(folder / "res")
    for normalize in ("none", "unit"):
        run = Run("holweg", WindowSize(windows=[50]), "datasets", 0, normalize=normalize)
        evaluate(both, run, store, progress=False)
    return read_results(folder / "res")


@pytest.mark.slow  # a simulated unit (the session's) and two runs: about 10 s on a busy machine
def test_a_real_run_keeps_its_normalizations_apart_and_out_of_the_ranks(transferred):
    blocks = build_report(transferred)
    text = render(blocks, "md")
    assert "holweg (normalize=unit)" in text and "across seeds" not in text
    assert "2 finished cells test on one class only and are not ranked" in text
    lone = next(t for t in blocks if isinstance(t, Table) and t.label == "tab:one-class")
    assert [r[1] for r in lone.rows] == ["holweg", "holweg (normalize=unit)"]
    assert all("(trained as OptoForce20 index)" in r[3] for r in lone.rows)
    assert SIMULATION_NOTE not in text  # univariate cells: no caution
