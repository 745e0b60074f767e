"""Datasets shaped like labs' recordings (issue 54, shapes in ``tests/labshapes.py``): what
balancing keeps is counted and said, and a detector that cannot learn from a cell's few
windows is skipped with the reason, not failed."""

from __future__ import annotations

import numpy as np
import pytest
from labshapes import few_windows, objects_as_materials

from slipbench.data.signals import Signals
from slipbench.data.transfer import combine
from slipbench.detectors.holweg import Holweg
from slipbench.engine import plan
from slipbench.engine.check import check_dataset
from slipbench.engine.runner import Run, evaluate
from slipbench.errors import UsageError
from slipbench.protocols.cross_instance import CrossInstance
from slipbench.protocols.window_size import WindowSize
from slipbench.store.results import ResultsStore


def test_balancing_within_objects_as_materials_is_counted_and_explained(tmp_path):
    # issue 54: each trial its own material; balancing per material keeps each slip stratum at
    # the smallest one's count, so most windows went unused without a word
    ds = objects_as_materials(tmp_path)
    store = ResultsStore(tmp_path / "out")
    within = Run("holweg", CrossInstance(), "grouped", labels="majority")
    rows = evaluate(ds, [within], store, progress=False)
    cell = rows[rows["cell"].str.contains('"test_instance": "index", "train_instance": "index"')]
    row = cell.iloc[0]
    assert row["balance"] == "within" and row["status"] == "ok"
    used, could = int(row["train_slip_windows"]), int(row["train_slip_available"])
    assert 2 * used < could  # the loss this issue is about, counted in the row
    warning = row["balance_warning"]
    assert warning.startswith(f"balancing kept {used} of {could} slip training windows")
    assert "each material holds one trial" in warning and "--balance across keeps" in warning
    # across materials: a documented choice, in the row and the key, that keeps more
    across = Run("holweg", CrossInstance(), "grouped", labels="majority", balance="across")
    more = evaluate(ds, [across], store, progress=False)
    twin = more[more["cell"] == row["cell"]].iloc[0]
    assert twin["balance"] == "across" and twin["key"] != row["key"]
    assert int(twin["train_slip_windows"]) > used
    assert int(twin["train_slip_available"]) == could  # the same windows before balancing
    assert 2 * int(twin["train_slip_windows"]) >= could
    # dataset check says the same, per cell
    checked = check_dataset(ds, [within]).cells
    line = checked[checked["cell"] == row["cell"]].iloc[0]
    assert line["train_slip"] == f"{used} of {could}"
    assert line["balance_warning"] == warning


def test_across_datasets_each_side_is_counted_and_named(tmp_path):
    train = objects_as_materials(tmp_path / "a", seed=0)
    ds = combine(train, objects_as_materials(tmp_path / "b", seed=1))
    run = Run("holweg", WindowSize(windows=[50]), "datasets", labels="majority")
    row = evaluate(ds, [run], ResultsStore(tmp_path / "out"), progress=False).iloc[0]
    # every window of each dataset's unit is available to its side: nothing is halved
    assert int(row["train_slip_available"]) == int(
        (
            Signals.from_dataset(train)
            .windows(
                50,
                np.flatnonzero(train.recordings["sensor_instance"] == row["sensor_instance"]),
                values=False,
                labelling="majority",
            )
            .y
            == 1
        ).sum()
    )
    warning = row["balance_warning"]
    assert f"Nano17 {row['sensor_instance']} of the training dataset at window 50: " in warning
    assert f"Nano17 {row['sensor_instance']} of the test dataset at window 50: " in warning


def test_evaluate_and_the_report_say_what_balancing_kept(tmp_path, cli):
    ds = objects_as_materials(tmp_path)
    out = tmp_path / "out"
    args = ["--dataset", str(ds.path), "--detector", "holweg", "--protocol", "cross-instance"]
    args += ["--labels", "majority", "--split", "grouped", "--quiet", "--out"]
    code, stdout, err = cli(["evaluate", *args, str(out)])
    assert code == 0, err
    assert "windows used of those available before balancing: train slip " in stdout
    warned = [line for line in err.splitlines() if line.startswith("warning: balancing kept")]
    assert len(warned) == 2  # one cause per unit, each naming the cells it concerns
    assert all(
        "in 8 cells of cross-instance" in w and "--balance across keeps" in w for w in warned
    )
    code, report, err = cli(["report", str(out)])
    assert code == 0, err
    assert "| Balancing " in report and "within material (the paper)" in report
    assert "Balancing kept under half of a class" in report
    code, stdout, err = cli(["evaluate", *args, str(tmp_path / "across"), "--balance", "across"])
    assert code == 0, err
    # across materials every slip window is kept; what remains is non-slip matched to slip
    assert "--balance across keeps" not in err and " slip training windows" not in err
    assert "slip has 31 windows, and non-slip is matched to it" in err


def test_within_material_keeps_the_keys_of_earlier_versions(tmp_path, monkeypatch):
    hashed: list[dict] = []
    real = plan.cell_key
    monkeypatch.setattr(plan, "cell_key", lambda d: hashed.append(d) or real(d))
    cell = Run("holweg", "window-size").cells(few_windows(tmp_path).recordings)[0]
    plan.keys(Run("holweg", "window-size"), cell, "fp")
    assert hashed and all("balance" not in d for d in hashed)
    hashed.clear()
    plan.keys(Run("holweg", "window-size", balance="across"), cell, "fp")
    assert all(d["balance"] == "across" for d in hashed)
    with pytest.raises(UsageError, match="unknown balancing 'per-object'"):
        Run("holweg", "window-size", balance="per-object")


def test_tcn_on_three_training_windows_is_skipped_with_the_reason(tmp_path, cli):
    pytest.importorskip("torch")
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
