"""A run says what it will cost before its first cell: cells cached and to run, and the time
from the cells of each detector already measured."""

from __future__ import annotations

import pytest
import toys
from datagen import subset

from slipbench.detectors.holweg import Holweg
from slipbench.engine.estimate import Cost, describe, duration
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
    fit = float(first["train_s"].median())
    test = float((first["infer_us_per_window"] * first["n_test"] / 1e6).median())
    work = 2 * fit + 2 * test  # two models of holweg to fit, two cells to test
    assert lines[0] == (
        f"holweg: 2 cells cached, 2 to run (2 models); about {duration(work)} of work "
        f"(median {fit:.3g} s a fit, {test:.3g} s a test, from 2 measured cells)"
    )
    assert lines[1].startswith("energy: 0 cells cached, 2 to run (2 models); no estimate yet")
    assert lines[2] == (
        f"total: 2 cells cached, 4 to run; about {duration(work)} with 1 worker(s), plus "
        "energy (no estimate yet)"
    )


def test_the_total_shares_the_work_among_the_workers():
    costs = {
        "lstm": Cost(cached=3, to_run=10, models=5, fit_s=60.0, test_s=0.5, measured=8),
        "holweg": Cost(cached=2, skipped=1, to_run=0),
    }
    lines = describe(costs, jobs=2)
    assert lines[0].endswith(
        "about 5 min of work (median 60 s a fit, 0.5 s a test, from 8 measured cells)"
    )
    assert lines[1] == "holweg: 2 cells cached, 1 skipped, 0 to run (0 models)"
    assert lines[2] == "total: 5 cells cached, 10 to run; about 3 min with 2 worker(s)"
    assert duration(3 * 3600) == "3.0 h" and duration(30) == "30 s"
