"""The engine trains the cells of a lockstep class together: the same rows as one at a time,
a member that cannot train failing alone, batches that keep every worker busy."""

from __future__ import annotations

import numpy as np
import pytest
import toys
from datagen import subset

from slipbench.detectors.holweg import Holweg
from slipbench.detectors.lstm import LSTM
from slipbench.engine.fitting import Job, Lockstep, TestSet, perform
from slipbench.engine.plan import Batch, PlannedCell, Task, batched
from slipbench.engine.runner import Run, evaluate
from slipbench.protocol import Cell, Part
from slipbench.protocols.window_size import WindowSize
from slipbench.store.results import ResultsStore

FIGURES = ["key", "model_key", "status", "reason", "accuracy", "accuracy_lo", "accuracy_hi"]


class Together(toys.Energy):
    """Energy that trains in lockstep, recording the size of every lockstep fit."""

    lockstep = True
    batches: list[int] = []

    @classmethod
    def _fit_lockstep(cls, detectors, data):
        cls.batches.append(len(detectors))
        for det, (x, y, seed, kw) in zip(detectors, data):
            det._fit(x, y, seed, **kw)


@pytest.fixture(scope="module")
def units(small):
    """The Nano17 units: window-size gives a model per unit and window."""
    return subset(small, small.recordings["sensor_type"].eq("Nano17"))


def _rows(dataset, detector, store, **options):
    run = Run(detector, WindowSize(windows=[50, 100]))
    rows = evaluate(dataset, run, store, progress=False, **options)
    return rows.sort_values("key").reset_index(drop=True)


@pytest.mark.slow  # three runs: 6 s
def test_the_engine_trains_models_of_one_window_together(units, tmp_path):
    Together.batches = []
    alone = _rows(units, Together(), ResultsStore(tmp_path / "a"), lockstep=False, jobs=0)
    assert Together.batches == []
    together = _rows(units, Together(), ResultsStore(tmp_path / "b"), jobs=0)
    n = len(together) // 2
    assert Together.batches == [n, n]  # one batch per window, every unit in it
    assert (together["status"] == "ok").all() and n >= 2
    assert together[FIGURES].equals(alone[FIGURES])
    again = _rows(units, Together(), ResultsStore(tmp_path / "b"), jobs=0)
    assert Together.batches == [n, n]  # cached cells never train again
    assert again[FIGURES].equals(together[FIGURES])


def test_the_switch_in_the_environment_turns_batches_off(units, tmp_path, monkeypatch):
    Together.batches = []
    monkeypatch.setenv("SLIPBENCH_LOCKSTEP", "0")
    _rows(units, Together(), ResultsStore(tmp_path), jobs=0)
    assert Together.batches == []


def _job(y, seed=1, n_tests=1):
    x = np.random.default_rng(seed).normal(size=(len(y), 30)).astype(np.float32)
    test = TestSet(x, np.r_[np.zeros(20), np.ones(20)].astype(np.int8), np.arange(40) // 4)
    return Job(Together(), seed, 1000.0, x, y, [test] * n_tests, name="together")


def test_a_member_that_cannot_train_fails_alone_with_its_reason():
    y = np.r_[np.zeros(20), np.ones(20)].astype(np.int8)
    jobs = [_job(y, 1), _job(np.zeros(40, np.int8), 2, n_tests=2), _job(y, 3)]
    Together.batches = []
    results = perform(Lockstep(jobs))
    assert [r.fields["status"] for r in results] == ["ok", "failed", "failed", "ok"]
    assert (
        "only class 0" in results[1].fields["reason"] and "(in fit)" in results[1].fields["reason"]
    )
    assert Together.batches == [2]  # the other two still trained together
    alone = perform(jobs[2])
    assert results[3].fields["accuracy"] == alone[0].fields["accuracy"]


def test_a_lockstep_fit_that_raises_falls_back_to_each_alone_and_says_so(monkeypatch):
    def broken(cls, detectors, data):
        raise RuntimeError("lanes exhausted")

    monkeypatch.setattr(Together, "_fit_lockstep", classmethod(broken))
    y = np.r_[np.zeros(20), np.ones(20)].astype(np.int8)
    results = perform(Lockstep([_job(y, 1), _job(y, 2)]))
    assert [r.fields["status"] for r in results] == ["ok", "ok"]
    assert all("lanes exhausted" in r.fields["warnings"] for r in results)


def _task(name: str, run: Run, window: int) -> Task:
    part = Part((("Nano17", "index"),), "train")
    cell = Cell({"window": window}, part, Part(part.sensors, "test"), window)
    return Task(name, [PlannedCell(run, cell, name, name)])


def test_batches_keep_every_worker_busy_and_stay_small():
    lstm, holweg = Run(LSTM(), WindowSize()), Run(Holweg(), WindowSize())
    tasks = [_task(f"a{i}", lstm, 50) for i in range(40)] + [_task("h", holweg, 50)]
    tasks += [_task(f"b{i}", lstm, 100) for i in range(4)]
    out = batched(tasks, workers=2, cap=16)
    assert sorted(pc.key for t in out for pc in t.cells) == sorted(t.model_key for t in tasks)
    assert [t.models for t in out] == [14, 13, 13, 1, 4]  # at most 16, in plan order
    assert isinstance(out[3], Task) and out[3].model_key == "h"  # holweg trains alone
    assert [t.models for t in batched(tasks[:4], workers=2)] == [2, 2]  # both workers busy
    assert [t.models for t in batched(tasks[:4], workers=1)] == [4]
    assert all(isinstance(t, Batch) for t in batched(tasks[:4], workers=1))


@pytest.mark.slow
def test_lstm_cells_trained_in_lockstep_equal_their_twins_alone(units, tmp_path):
    fast = {"max_epochs": 2, "hidden_size": 4}
    alone = _rows(units, LSTM(**fast), ResultsStore(tmp_path / "a"), lockstep=False, jobs=2)
    together = _rows(units, LSTM(**fast), ResultsStore(tmp_path / "b"), jobs=2)
    assert (together["status"] == "ok").all() and len(together) >= 4
    assert together[FIGURES + ["tp_rate", "tn_rate", "epochs"]].equals(
        alone[FIGURES + ["tp_rate", "tn_rate", "epochs"]]
    )
    # trained together: one batch per window, its training time shared by its models
    assert together.groupby("window")["train_s"].nunique().eq(1).all()
