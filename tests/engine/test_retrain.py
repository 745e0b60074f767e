"""Retraining draws: a run's models trained again from another draw of the detector's seed, on
the same split, so that retraining noise is measured apart from the split's (the calibration of
a bench)."""

from __future__ import annotations

import pandas as pd
import pytest
import toys
from datagen import subset

from slipbench.detectors.holweg import Holweg
from slipbench.engine.fitting import Job
from slipbench.engine.plan import keys
from slipbench.engine.runner import Run, evaluate
from slipbench.errors import UsageError
from slipbench.protocol import Cell, Part
from slipbench.protocols.window_size import WindowSize
from slipbench.seeding import seed_int
from slipbench.store.results import ResultsStore

UNIT = (("Nano17", "index"),)


@pytest.fixture(scope="module")
def index(small):
    return subset(
        small,
        small.recordings["sensor_type"].eq("Nano17")
        & small.recordings["sensor_instance"].eq("index"),
    )


def _rows(data, run, folder):
    rows = evaluate(data, run, ResultsStore(folder), progress=False)
    return rows.set_index("cell").sort_index()


def test_draw_zero_is_the_run_and_its_seed_is_unchanged():
    job = Job(Holweg(), 7, 1000.0, None, None, [])
    assert job.fit_seed == seed_int(7, "detector")  # the seed every earlier run trained from
    assert Job(Holweg(), 7, 1000.0, None, None, [], draw=1).fit_seed != job.fit_seed
    run = Run(Holweg(), WindowSize(), seed=7)
    assert run.retrain == 0 and run.retrained(0).retrain == 0
    twin = run.retrained(2)
    assert twin.retrain == 2 and run.retrain == 0 and twin.seed == run.seed
    for bad in (-1, 1.5, True):
        with pytest.raises(UsageError, match="retraining draw"):
            run.retrained(bad)


def test_draw_zero_keeps_the_keys_and_another_draw_changes_them():
    cell = Cell({"window": 50}, Part(UNIT, "train"), Part(UNIT, "test"), 50)
    run = Run(toys.Coin(), WindowSize(), split="grouped", seed=3)
    assert keys(run.retrained(0), cell, "f") == keys(run, cell, "f")
    assert set(keys(run.retrained(1), cell, "f")).isdisjoint(keys(run, cell, "f"))


def test_a_draw_retrains_a_seeded_detector_on_the_same_split(index, tmp_path):
    """Coin's scores come from its fit seed: another draw changes its figures, while the
    cell's test set (the split) stays the run's."""
    run = Run(toys.Coin(), WindowSize(windows=[50]), split="grouped", seed=3)
    one = _rows(index, run, tmp_path / "one")
    twin = _rows(index, run.retrained(1), tmp_path / "twin")
    assert (one["status"] == "ok").all() and len(one) == len(twin) == 1
    same_split = ["n_test", "test_slip_windows", "test_nonslip_windows", "n_test_trials"]
    pd.testing.assert_frame_equal(one[same_split], twin[same_split])
    assert (one["accuracy"] != twin["accuracy"]).all()


def test_a_detector_that_draws_nothing_gives_the_same_figures_under_every_draw(index, tmp_path):
    run = Run(Holweg(), WindowSize(windows=[50]), split="grouped", seed=3)
    one = _rows(index, run, tmp_path / "one")
    twin = _rows(index, run.retrained(1), tmp_path / "twin")
    figures = ["accuracy", "tn_rate", "tp_rate", "accuracy_lo", "accuracy_hi"]
    pd.testing.assert_frame_equal(one[figures], twin[figures])
    assert (one["key"] != twin["key"]).all()
