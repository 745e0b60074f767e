"""A run says what it will cost before its first cell: cells cached and to run, and the time
from the cells of each detector already measured."""

from __future__ import annotations

import pytest
import toys
from datagen import subset

from slipbench.detectors.holweg import Holweg
from slipbench.engine.estimate import Cost, describe, duration, makespan
from slipbench.engine.runner import Run, evaluate
from slipbench.protocols.window_size import WindowSize
from slipbench.store.results import ResultsStore


@pytest.mark.slow  # two runs: 7 s
def test_a_run_of_several_detectors_prints_its_cost_first(small, tmp_path, capsys):
    rec = small.recordings
    index = subset(small, rec["sensor_type"].eq("Nano17") & rec["sensor_instance"].eq("index"))
    store, windows = ResultsStore(tmp_path), WindowSize(windows=[50, 100])
    first = evaluate(index, Run(Holweg(), windows), store, progress=False)
    runs = [Run(Holweg(), windows), Run(Holweg(keep=0.7), windows), Run(toys.Energy(), windows)]
    evaluate(index, runs, store, jobs=0)
    lines = capsys.readouterr().err.splitlines()
    # each model: its training samples at the measured rate, scoring them, testing its cell
    per_sample = float(first["train_s"].sum() / (first["n_train"] * first["window"]).sum())
    score = float((first["infer_us_per_window"] * first["n_test"]).sum() / first["n_test"].sum())
    test = float(first["test_s"].sum() / first["n_test"].sum())
    work = sum(
        n_train * (per_sample * window + score / 1e6) + n_test * test
        for n_train, window, n_test in zip(first["n_train"], first["window"], first["n_test"])
    )
    # the cells to run are holweg's with keep=0.7: charged at the rates of its other rows
    assert lines[0] == (
        f"holweg: 2 cells cached, 2 to run (2 models); about {duration(work)} of work "
        "(from 2 measured cells of other parameters)"
    )
    assert lines[1].startswith("energy: 0 cells cached, 2 to run (2 models); no estimate yet")
    assert lines[2].startswith("total: 2 cells cached, 4 to run; about ")
    assert lines[2].endswith("with 1 worker(s), plus energy (no estimate yet)")


def test_the_total_shares_the_work_among_the_workers_longest_first():
    costs = {
        "lstm": Cost(cached=3, to_run=10, models=5, model_s=[120.0] * 4 + [60.0], measured=8),
        "holweg": Cost(cached=2, skipped=1, to_run=0),
        "tcn": Cost(to_run=1, models=1, model_s=[60.0], measured=2, alike=False),
    }
    lines = describe(costs, jobs=2)
    assert lines[0].endswith("about 9 min of work (from 8 measured cells)")
    assert lines[1] == "holweg: 2 cells cached, 1 skipped, 0 to run (0 models)"
    assert lines[2].endswith("about 60 s of work (from 2 measured cells of other parameters)")
    # 4 x 120 s and 2 x 60 s on two workers: 300 s each, the longest first
    assert lines[3] == "total: 5 cells cached, 11 to run; about 5 min with 2 worker(s)"
    assert makespan([120.0] * 4 + [60.0] * 2, 2) == 300.0 and makespan([500.0, 1, 1], 3) == 500
    assert duration(3 * 3600) == "3.0 h" and duration(30) == "30 s"
