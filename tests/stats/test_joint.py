"""Means over fingers get one joint bootstrap over the trials the fingers share: the same
point estimate as the rows, an interval from the stored predictions, and the report says which
interval it shows."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from slipbench.detectors.holweg import Holweg
from slipbench.engine.runner import Run, evaluate
from slipbench.protocols.window_size import WindowSize
from slipbench.report.document import build_report, render
from slipbench.report.presentation import shown_protocol
from slipbench.stats.joint import joint_means
from slipbench.store.results import ResultsStore


@pytest.fixture(scope="module")
def run(small, tmp_path_factory):
    folder = tmp_path_factory.mktemp("joint")
    rows = evaluate(
        small,
        Run(Holweg(), WindowSize(windows=(50,)), split="grouped"),
        ResultsStore(folder),
        progress=False,
    )
    return rows, folder


def test_the_joint_mean_is_the_mean_of_the_fingers_and_its_interval_holds_it(run):
    rows, folder = run
    joint = joint_means(rows, ["detector", "sensor_type"], [folder])
    assert {k[1] for k in joint} == set(rows["sensor_type"])
    for (_detector, sensor), j in joint.items():
        fingers = rows[rows["sensor_type"] == sensor]
        assert j["accuracy"] == pytest.approx(fingers["accuracy"].mean(), abs=1e-12)
        assert j["n_test_sets"] == len(fingers)
        for name in ("accuracy", "tp_rate", "tn_rate"):
            assert j[f"{name}_lo"] <= j[name] <= j[f"{name}_hi"]
            assert np.isfinite(j[f"{name}_lo"]) and np.isfinite(j[f"{name}_hi"])


def test_a_group_with_a_missing_predictions_file_gets_nothing(run, tmp_path):
    rows, folder = run
    (tmp_path / "predictions").mkdir()
    kept = rows[rows["sensor_type"] != "Nano17"]
    for key in kept["key"]:
        (tmp_path / "predictions" / f"{key}.parquet").write_bytes(
            (folder / "predictions" / f"{key}.parquet").read_bytes()
        )
    joint = joint_means(rows, ["detector", "sensor_type"], [tmp_path])
    assert {k[1] for k in joint} == set(kept["sensor_type"])


@pytest.mark.parametrize("damage", ["torn", "foreign"])
def test_a_damaged_predictions_file_costs_its_group_the_joint_interval_not_the_report(
    run, tmp_path, damage
):
    rows, folder = run
    (tmp_path / "predictions").mkdir()
    for key in rows["key"]:
        (tmp_path / "predictions" / f"{key}.parquet").write_bytes(
            (folder / "predictions" / f"{key}.parquet").read_bytes()
        )
    torn = rows[rows["sensor_type"] == "Nano17"]["key"].iloc[0]
    path = tmp_path / "predictions" / f"{torn}.parquet"
    if damage == "torn":
        path.write_bytes(b"PAR1 torn")
    else:  # a Parquet file of other columns
        pd.DataFrame({"recording_id": ["a"], "window_index": [0]}).to_parquet(path)
    why = "lacks the columns y_true, score" if damage == "foreign" else ""
    with pytest.warns(UserWarning, match=f"{torn}.parquet: not a readable predictions file.*{why}"):
        joint = joint_means(rows, ["detector", "sensor_type"], [tmp_path])
    assert {k[1] for k in joint} == set(rows["sensor_type"]) - {"Nano17"}
    with pytest.warns(UserWarning, match="not a readable predictions file"):
        text = render(build_report(rows, intervals=True, predictions=[tmp_path]), "md")
    # the other sensors keep the joint interval; the note names the one that fell back to the rows
    assert "one bootstrap over the trials the fingers share" in text
    assert (
        "for Nano17 (holweg), whose predictions are missing or unreadable, the fingers' half-widths combined"
        in text
    )


def test_the_report_says_which_interval_an_average_has(run):
    rows, folder = run
    joint = render(build_report(rows, intervals=True, predictions=[folder]), "md")
    rows_only = render(build_report(rows, intervals=True), "md")
    assert "one bootstrap over the trials the fingers share" in joint
    assert "combined as independent, which understates it" in rows_only


@pytest.mark.slow
def test_seeds_pool_into_one_interval(small, tmp_path):
    """Two seeds of one cell: the table shows one interval of their mean, the two-level
    bootstrap over trials and seeds, not the one from the seeds' rows, and says so."""
    from slipbench.report.document import protocol_tables

    store = ResultsStore(tmp_path)
    rows = evaluate(
        small,
        [Run(Holweg(), WindowSize(windows=(50,)), split="grouped", seed=s) for s in (0, 1)],
        store,
        progress=False,
    )
    layout = shown_protocol(WindowSize(windows=(50,)), "window-size")
    pooled = joint_means(rows, ["sensor_type", "sensor_instance", "window"], [tmp_path])
    assert len(pooled) == rows[["sensor_type", "sensor_instance"]].drop_duplicates().shape[0]
    ((_, table),) = protocol_tables(
        rows, layout, "window-size", "holweg", intervals=True, predictions=[tmp_path]
    )
    ((_, averaged),) = protocol_tables(rows, layout, "window-size", "holweg", intervals=True)
    assert table.cells != averaged.cells  # same means, other bounds
    key = next(iter(pooled))
    one = pooled[key]
    assert f"[{100 * one['accuracy_lo']:.1f}, {100 * one['accuracy_hi']:.1f}]" in " ".join(
        c for line in table.cells for c in line
    )
    assert any("two-level bootstrap over test trials and seeds" in n for n in table.notes)
    assert any("its interval from the seeds' rows" in n for n in averaged.notes)


@pytest.mark.slow
def test_seeds_pooled_for_some_figures_only_say_so(small, tmp_path):
    """A figure whose seeds' predictions are gone gets its interval from the seeds' rows, and the
    note counts the figures of each kind instead of calling every interval pooled."""
    from slipbench.report.document import protocol_tables

    rows = evaluate(
        small,
        [Run(Holweg(), WindowSize(windows=(50,)), split="grouped", seed=s) for s in (0, 1)],
        ResultsStore(tmp_path),
        progress=False,
    )
    gone = rows[(rows["sensor_type"] == "Nano17") & (rows["seed"] == 1)]["key"]
    for key in gone:
        (tmp_path / "predictions" / f"{key}.parquet").unlink()
    layout = shown_protocol(WindowSize(windows=(50,)), "window-size")
    ((_, table),) = protocol_tables(
        rows, layout, "window-size", "holweg", intervals=True, predictions=[tmp_path]
    )
    figures = rows[["sensor_type", "sensor_instance"]].drop_duplicates()
    pooled = len(figures) - len(gone)
    assert pooled > 0
    assert any(
        f"for the {len(gone)} of the {len(figures)} such figures whose predictions are missing or "
        "unreadable, its interval from the seeds' rows" in n
        for n in table.notes
    )
