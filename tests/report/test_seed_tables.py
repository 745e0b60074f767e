"""Tables of cells run under several seeds (``--repeats``): the mean over seeds with the two-level
interval over test trials and seeds, from a results store of 3 seeds per cell; wider than the
one-seed interval when the seeds differ, the same when they do not; the note says which
interval a figure has, with the seeds and trials behind it."""

from __future__ import annotations

import numpy as np
import pytest
from storegen import repeats_store

from slipbench.protocols.window_size import WindowSize
from slipbench.report.document import protocol_tables
from slipbench.report.presentation import shown_protocol
from slipbench.report.tables import baseline_table, summarize
from slipbench.stats.joint import joint_means
from slipbench.stats.metrics import Predictions, mean_over_test_sets, pool_seeds
from slipbench.store.results import read_predictions, read_results

LAYOUT = shown_protocol(WindowSize(windows=(50, 200)), "window-size")
KEYS = ["sensor_type", "sensor_instance", "window"]


def _table(rows, folder=None):
    ((_, table),) = protocol_tables(
        rows,
        LAYOUT,
        "window-size",
        "holweg",
        intervals=True,
        predictions=[folder] if folder else (),
    )
    return table


def _parts(folder, rows) -> list[Predictions]:
    """The rows' predictions, in the rows' order."""
    out = []
    for key in rows["key"]:
        p = read_predictions(folder, key)
        out.append(
            Predictions(
                p["y_true"].to_numpy(bool),
                p["score"].to_numpy() >= 0.5,
                p["trial"].to_numpy(),
                p["score"].to_numpy(),
            )
        )
    return out


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    folder = tmp_path_factory.mktemp("repeats")
    repeats_store(folder)
    return folder, read_results(folder)


def test_three_seeds_show_their_mean_with_the_two_level_interval(store):
    folder, rows = store
    table = _table(rows, folder)
    text = " ".join(c for line in table.cells for c in line)
    assert "±" not in text  # the spread over seeds is inside the interval
    for (_, finger, window), cell in rows.groupby(KEYS):
        parts = _parts(folder, cell.sort_values("seed"))
        two = pool_seeds(parts, seed=0)
        assert two["accuracy"] == pytest.approx(cell["accuracy"].mean(), abs=1e-12)
        shown = f"{100 * two['accuracy']:.1f} [{100 * two['accuracy_lo']:.1f}, {100 * two['accuracy_hi']:.1f}]"
        assert shown in text, (finger, window)
        # wider than one seed's own interval and than the one-level bootstrap of the same seeds
        one_level = mean_over_test_sets(parts, seed=0)
        width = two["accuracy_hi"] - two["accuracy_lo"]
        assert width > one_level["accuracy_hi"] - one_level["accuracy_lo"]
        first = cell.sort_values("seed").iloc[0]
        assert width > first["accuracy_hi"] - first["accuracy_lo"]
    (note,) = [n for n in table.notes if n.startswith("[95 % interval")]
    assert "a figure run under 3 seeds (16 slip and 16 non-slip test trials) is their mean" in note
    assert "two-level bootstrap over test trials and seeds" in note


def test_seeds_that_do_not_differ_give_the_one_seed_interval(tmp_path):
    repeats_store(tmp_path, same_seeds=True)
    rows = read_results(tmp_path)
    for _, cell in rows.groupby(KEYS):
        parts = _parts(tmp_path, cell.sort_values("seed"))
        two, one = pool_seeds(parts, seed=0), mean_over_test_sets(parts[:1], seed=0)
        for bound in ("accuracy_lo", "accuracy_hi"):
            assert two[bound] == pytest.approx(one[bound], abs=1e-9)


def test_without_predictions_the_interval_comes_from_the_seeds_rows(store):
    folder, rows = store
    table = _table(rows)
    text = " ".join(c for line in table.cells for c in line)
    summary = summarize(rows, KEYS)
    for r in summary.itertuples():
        assert f"{100 * r.mean:.1f} [{100 * r.lo:.1f}, {100 * r.hi:.1f}]" in text
        cell = rows[(rows["sensor_instance"] == r.sensor_instance) & (rows["window"] == r.window)]
        # retraining noise inside: at least the seeds' spread, wider than the mean of their bounds
        assert r.hi - r.lo > (cell["accuracy_hi"] - cell["accuracy_lo"]).mean()
    (note,) = [n for n in table.notes if n.startswith("[95 % interval")]
    assert (
        "3 seeds (16 slip and 16 non-slip test trials per seed) is their mean, its interval from the seeds' rows"
        in note
    )


def test_a_figure_whose_seed_lost_its_predictions_falls_back_and_the_note_counts(store, tmp_path):
    folder, rows = store
    (tmp_path / "predictions").mkdir()
    gone = rows[(rows["sensor_instance"] == "index") & (rows["window"] == 50) & (rows["seed"] == 2)]
    for key in rows["key"]:
        if key not in set(gone["key"]):
            name = f"{key}.parquet"
            (tmp_path / "predictions" / name).write_bytes(
                (folder / "predictions" / name).read_bytes()
            )
    table = _table(rows, tmp_path)
    (note,) = [n for n in table.notes if n.startswith("[95 % interval")]
    assert (
        "for the 1 of the 4 such figures whose predictions are missing or unreadable, its interval from the seeds' rows"
        in note
    )


def test_the_mean_over_fingers_pools_fingers_and_seeds(store):
    folder, rows = store
    at50 = rows[rows["window"] == 50]
    joint = joint_means(at50, ["detector", "sensor_type"], [folder])
    j = joint[("holweg", "Nano17")]
    assert j["n_seeds"] == 3 and j["n_test_sets"] == 6
    assert j["accuracy"] == pytest.approx(at50["accuracy"].mean(), abs=1e-12)
    per_seed = [
        _parts(folder, at50[at50["seed"] == s].sort_values("sensor_instance")) for s in (0, 1, 2)
    ]
    direct = pool_seeds(per_seed, seed=0)
    assert (j["accuracy_lo"], j["accuracy_hi"]) == pytest.approx(
        (direct["accuracy_lo"], direct["accuracy_hi"])
    )
    one_level = mean_over_test_sets([p for seed in per_seed for p in seed], seed=0)
    assert j["accuracy_hi"] - j["accuracy_lo"] > one_level["accuracy_hi"] - one_level["accuracy_lo"]
    table = baseline_table(rows, intervals=True, joint=joint)
    assert table is not None
    assert f"[{100 * j['accuracy_lo']:.1f}, {100 * j['accuracy_hi']:.1f}]" in table.cells[0][0]
    assert any("the seeds drawn too, so retraining noise is inside it" in n for n in table.notes)


def test_seeds_that_finished_different_cells_are_not_pooled(store):
    folder, rows = store
    at50 = rows[rows["window"] == 50]
    lost = at50[~((at50["seed"] == 1) & (at50["sensor_instance"] == "middle"))]
    assert joint_means(lost, ["detector", "sensor_type"], [folder]) == {}
    assert np.isfinite(summarize(lost, KEYS)["lo"]).all()
