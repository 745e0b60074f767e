"""Runs: shared models, resume after a kill, executors (process pool, dask), time limits."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
import toys
from datagen import subset

from slipbench.detectors.holweg import Holweg
from slipbench.engine.runner import Run, evaluate
from slipbench.errors import UsageError
from slipbench.protocols.material_holdout import MaterialHoldout
from slipbench.protocols.window_size import WindowSize
from slipbench.store.results import ResultsStore

SLOW = toys.source(toys.Slow)


@pytest.fixture(scope="module")
def index(small):
    """One Nano17 unit: 6 window-size cells."""
    return subset(
        small,
        small.recordings["sensor_type"].eq("Nano17")
        & small.recordings["sensor_instance"].eq("index"),
    )


def _figures(rows: pd.DataFrame) -> pd.DataFrame:
    return rows.set_index("key")[
        ["accuracy", "accuracy_lo", "accuracy_hi", "tp_rate", "tn_rate"]
    ].sort_index()


@pytest.mark.slow
def test_models_are_shared_between_protocols(index, tmp_path):
    runs = [Run(Holweg(), WindowSize()), Run(Holweg(), MaterialHoldout())]
    rows = evaluate(index, runs, ResultsStore(tmp_path), progress=False)
    assert len(rows) == 6 + 10 and (rows["status"] == "ok").all()
    ws50 = rows[(rows["protocol"] == "window-size") & (rows["window"] == 50)].iloc[0]
    with_rows = rows[rows["training"].eq("with")]
    assert (with_rows["model_key"] == ws50["model_key"]).all()
    assert (with_rows["train_s"] == ws50["train_s"]).all()  # trained once
    assert rows[rows["training"].eq("without")]["model_key"].nunique() == 5


@pytest.mark.slow
def test_models_are_reused_by_a_later_command(index, tmp_path):
    store = ResultsStore(tmp_path)
    ws = evaluate(index, Run(Holweg(), WindowSize()), store, progress=False)
    assert len(list((tmp_path / "models").glob("*.npz"))) == 6
    mh = evaluate(index, Run(Holweg(), MaterialHoldout()), store, progress=False)
    ws50 = ws[ws["window"] == 50].iloc[0]
    with_rows = mh[mh["training"] == "with"]
    assert (with_rows["model_key"] == ws50["model_key"]).all()
    assert (with_rows["train_s"] == ws50["train_s"]).all()  # loaded, not refitted
    assert len(list((tmp_path / "models").glob("*.npz"))) == 6 + 5
    forced = evaluate(index, Run(Holweg(), MaterialHoldout()), store, force=True, progress=False)
    assert (
        forced.loc[forced["training"] == "with", "train_s"] != ws50["train_s"]
    ).all()  # --force refits
    pd.testing.assert_frame_equal(_figures(forced), _figures(mh))


@pytest.mark.slow
def test_process_pool_gives_the_same_results(index, tmp_path):
    run = Run(Holweg(), WindowSize(), seed=3)
    local = evaluate(index, run, ResultsStore(tmp_path / "a"), progress=False)
    pooled = evaluate(index, run, ResultsStore(tmp_path / "b"), jobs=2, progress=False)
    pd.testing.assert_frame_equal(_figures(local), _figures(pooled))


@pytest.mark.slow
def test_dask_local_cluster_gives_the_same_results(index, tmp_path):
    distributed = pytest.importorskip("distributed")
    run = Run(Holweg(), WindowSize(), seed=3)
    local = evaluate(index, run, ResultsStore(tmp_path / "a"), progress=False)
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        remote = evaluate(
            index,
            run,
            ResultsStore(tmp_path / "b"),
            scheduler=cluster.scheduler_address,
            progress=False,
        )
    pd.testing.assert_frame_equal(_figures(local), _figures(remote))


@pytest.mark.slow
def test_unreachable_scheduler_is_named(index, tmp_path):
    pytest.importorskip("distributed")
    run = Run(Holweg(), WindowSize())
    with pytest.raises(UsageError, match="cannot reach the dask scheduler at tcp://127.0.0.1:9"):
        evaluate(index, run, ResultsStore(tmp_path), scheduler="tcp://127.0.0.1:9", progress=False)


@pytest.mark.slow
def test_seeds_change_the_draw_and_repeat_exactly(index, tmp_path):
    a = evaluate(
        index, Run(Holweg(), WindowSize(), seed=1), ResultsStore(tmp_path / "a"), progress=False
    )
    b = evaluate(
        index, Run(Holweg(), WindowSize(), seed=1), ResultsStore(tmp_path / "b"), progress=False
    )
    c = evaluate(
        index, Run(Holweg(), WindowSize(), seed=2), ResultsStore(tmp_path / "c"), progress=False
    )
    pd.testing.assert_frame_equal(_figures(a), _figures(b))
    assert not np.allclose(a["accuracy"], c["accuracy"])


@pytest.mark.slow
def test_time_limit_reports_timeout(index, tmp_path, monkeypatch):
    (tmp_path / "plugins").mkdir()
    (tmp_path / "plugins" / "slow.py").write_text(SLOW)
    from slipbench.base import BaseDetector
    from slipbench.engine.registry import Registry

    reg = Registry("detector", BaseDetector, "slipbench.detectors")
    reg.add_folder(tmp_path / "plugins")
    slow = reg.get("slow")
    rows = evaluate(
        index,
        Run(slow(seconds=5.0), WindowSize()),
        ResultsStore(tmp_path / "r"),
        cell_timeout=0.5,
        progress=False,
    )
    assert (rows["status"] == "timeout").all()
    assert rows["reason"].str.contains("within 0.5 s").all()


@pytest.mark.slow
def test_missing_class_is_skipped_with_its_reason(small, tmp_path):
    rec = small.recordings
    no_neoprene_press = subset(
        small,
        rec["sensor_type"].eq("Nano17")
        & rec["sensor_instance"].eq("index")
        & ~(rec["scenario"].eq("press") & rec["material"].eq("neoprene")),
    )
    rows = evaluate(
        no_neoprene_press, Run(Holweg(), MaterialHoldout()), ResultsStore(tmp_path), progress=False
    )
    skipped = rows[rows["status"] == "skipped"]
    assert set(skipped["material"]) == {"neoprene"} and len(skipped) == 2
    assert (skipped["reason"] == "no non-slip windows to test on").all()
    stored = pq.read_table(tmp_path / "results.parquet").to_pandas()
    assert (stored["status"] == "skipped").sum() == 2


@pytest.mark.slow
def test_kill_and_resume(small_path, tmp_path):
    """SIGKILL a run mid-way: the results on disk stay readable, and rerunning the command
    recomputes only what had not finished."""
    plugins = tmp_path / "plugins"
    plugins.mkdir()
    (plugins / "slow.py").write_text(SLOW)
    out = tmp_path / "res"
    argv = [
        sys.executable,
        "-m",
        "slipbench.app.cli",
        "evaluate",
        "--detector",
        "slow",
        "--protocol",
        "window-size",
        "--dataset",
        str(small_path),
        "--out",
        str(out),
        "--plugins",
        str(plugins),
        "--quiet",
    ]
    # from outside the source tree, so that `slipbench` is the installed package
    proc = subprocess.Popen(
        argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=tmp_path
    )
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list((out / "cells").glob("*.parquet"))) < 5:
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    _, err = proc.communicate()
    done = {p.name: p.stat().st_mtime_ns for p in (out / "cells").glob("*.parquet")}
    assert 5 <= len(done) < 48, f"the run should have been killed mid-way: {err}"
    for path in (out / "cells").glob("*.parquet"):
        pq.read_table(path)  # every stored cell is whole
    finished = subprocess.run(argv, capture_output=True, text=True, cwd=tmp_path)
    assert finished.returncode == 0, finished.stderr
    rows = pq.read_table(out / "results.parquet").to_pandas()
    assert len(rows) == 48 and (rows["status"] == "ok").all()
    for name, mtime in done.items():
        assert (out / "cells" / name).stat().st_mtime_ns == mtime  # not recomputed


KILLED = toys.source(toys.Doomed)


@pytest.mark.slow
@pytest.mark.parametrize("jobs", [1, 2])
def test_a_worker_killed_by_the_system_fails_its_cells_and_the_run_goes_on(index, tmp_path, jobs):
    from slipbench.base import BaseDetector
    from slipbench.engine.registry import Registry

    (tmp_path / "plugins").mkdir()
    (tmp_path / "plugins" / "doomed.py").write_text(KILLED)
    reg = Registry("detector", BaseDetector, "slipbench.detectors")
    reg.add_folder(tmp_path / "plugins")
    rows = evaluate(
        index,
        Run(reg.get("doomed")(), WindowSize()),
        ResultsStore(tmp_path / "r"),
        jobs=jobs,
        progress=False,
    )
    dead = rows[rows["window"] == 5]
    assert (dead["status"] == "failed").all()
    assert dead["reason"].str.startswith("the worker process was killed by signal 9").all()
    assert dead["reason"].str.endswith(" in fit").all()
    assert (rows.loc[rows["window"] > 5, "status"] == "ok").all()
