"""Datasets shaped like labs' recordings (issue 54, shapes in ``tests/labshapes.py``): what
balancing keeps is counted and said, and a detector that cannot learn from a cell's few
windows is skipped with the reason, not failed."""

from __future__ import annotations

import numpy as np
import pytest
from labshapes import few_windows

from slipbench.detectors.holweg import Holweg
from slipbench.engine.runner import Run, evaluate
from slipbench.errors import UsageError
from slipbench.protocols.window_size import WindowSize
from slipbench.store.results import ResultsStore

pytest.importorskip("torch")


def test_tcn_on_three_training_windows_is_skipped_with_the_reason(tmp_path, cli):
    ds = few_windows(tmp_path)
    runs = [Run(d, WindowSize(windows=[100])) for d in ("tcn", "holweg")]
    rows = evaluate(ds, runs, ResultsStore(tmp_path / "out"), progress=False)
    tcn = rows[rows["detector"] == "tcn"].iloc[0]
    assert int(tcn["train_slip_windows"]) + int(tcn["train_nonslip_windows"]) == 3
    assert tcn["status"] == "skipped"
    assert tcn["reason"].startswith("tcn needs at least 2 training windows of each class")
    assert rows.loc[rows["detector"] == "holweg", "status"].iloc[0] == "ok"
    code, out, err = cli(
        [
            "evaluate",
            "--dataset",
            str(ds.path),
            "--detector",
            "tcn",
            "--protocol",
            "window-size",
            "--protocol-param",
            "windows=[100]",
            "--out",
            str(tmp_path / "cli"),
            "--quiet",
        ]
    )
    assert code == 0, err
    assert err.count("tcn needs at least 2 training windows") == 1  # listed once
    # the Python API says the same before any training
    from slipbench.detectors.tcn import TCN

    x = np.random.default_rng(0).normal(size=(3, 100)).astype(np.float32)
    with pytest.raises(UsageError, match="holds 2 slip and 1 non-slip"):
        TCN().fit(x, np.array([1, 1, 0]), sampling_rate=100.0)
    Holweg().fit(x, np.array([1, 1, 0]), sampling_rate=100.0)  # one window of a class will do
