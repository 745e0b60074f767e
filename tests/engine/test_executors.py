"""Executors (issues 32 and 33): plugin code that ends its process never ends a run with exit 0
and never hangs it; every executor sets the threads a model may use; a model's progress
reaches the parent from this process and from workers."""

from __future__ import annotations

import json

import numpy as np
import pytest
import toys
from datagen import subset

from slipbench.engine import threads
from slipbench.engine.fitting import Job, fit_and_test
from slipbench.engine.runner import Run, evaluate
from slipbench.protocols.window_size import WindowSize
from slipbench.store.results import ResultsStore, cells_failed
from slipbench.stream.cell import Recordings, StreamTest


@pytest.fixture(scope="module")
def index(small):
    """One Nano17 unit."""
    rec = small.recordings
    return subset(small, rec["sensor_type"].eq("Nano17") & rec["sensor_instance"].eq("index"))


def _rows(index, tmp_path, detector, jobs, **options):
    return evaluate(
        index,
        Run(detector, WindowSize(windows=[50])),
        ResultsStore(tmp_path / f"r{jobs}"),
        jobs=jobs,
        progress=False,
        **options,
    )


WORKERS = [pytest.param(j, marks=pytest.mark.slow) for j in (1, 2)]  # a pool starts in seconds


@pytest.mark.parametrize("jobs", [0, *WORKERS])
@pytest.mark.parametrize(
    "toy, said",
    [
        (toys.ExitsInFit, "detector 'exits-in-fit' raised SystemExit(0) in fit"),
        (toys.ExitsInPredict, "detector 'exits-in-predict' raised SystemExit(3) in test"),
    ],
)
def test_sys_exit_in_plugin_code_fails_its_cells(index, tmp_path, toy, said, jobs):
    rows = _rows(index, tmp_path, toy(), jobs)
    assert len(rows) and (rows["status"] == "failed").all()
    assert rows["reason"].str.startswith(said).all()
    assert cells_failed(rows) is not None  # exit 4, not 0


def test_sys_exit_in_a_stream_fails_its_cell():
    rng = np.random.default_rng(0)
    x, y = rng.normal(size=(40, 20)), np.tile([0, 1], 20)
    recordings = Recordings(
        [rng.normal(size=400)], [np.zeros(400, bool)], ["t"], ["press"], ["r"], [1000.0]
    )
    stream = StreamTest(recordings, recordings, 10, 200.0)
    ((fields, _),) = fit_and_test(Job(toys.ExitsInStream(), 0, 1000.0, x, y, [stream]))
    assert fields["status"] == "failed"
    assert fields["reason"].startswith("detector 'exits-in-stream' raised SystemExit(0) in test")


@pytest.mark.slow
@pytest.mark.parametrize("toy, phase", [(toys.VanishesInFit, "fit"), (toys.VanishesInTest, "test")])
@pytest.mark.parametrize("timeout", [None, 30.0])
def test_a_worker_that_exits_with_code_0_fails_its_cells_and_never_hangs(
    index, tmp_path, toy, phase, timeout
):
    rows = _rows(index, tmp_path, toy(), 1, cell_timeout=timeout)
    assert (rows["status"] == "failed").all()  # not "timeout", and no wait for the limit
    assert (rows["reason"] == f"the worker process exited with code 0 in {phase}").all()


def _seen(rows) -> dict:
    ((fitted,),) = rows[["fitted"]].to_numpy()
    return json.loads(fitted)["threads"]


@pytest.mark.slow
def test_a_worker_sees_its_share_of_the_cores(index, tmp_path):
    seen = _seen(_rows(index, tmp_path, toys.ThreadProbe(), 2))
    share = threads.share(2)
    assert seen["numba"] == share and seen["blas"] == [share]
    assert seen["omp_env"] == str(share)  # for libraries a model imports later


def test_an_in_process_fit_sees_the_limits_and_the_caller_keeps_its_own(index, tmp_path):
    numba = pytest.importorskip("numba")
    from threadpoolctl import threadpool_info, threadpool_limits

    cores = threads.cores()
    mine = max(1, cores - 1)  # the caller's own settings, unlike the run's (all cores)
    before = numba.get_num_threads()
    with threadpool_limits(limits=mine):
        numba.set_num_threads(min(mine, numba.config.NUMBA_NUM_THREADS))
        try:
            seen = _seen(_rows(index, tmp_path, toys.ThreadProbe(), 0))
            after = numba.get_num_threads(), {p["num_threads"] for p in threadpool_info()}
        finally:
            numba.set_num_threads(before)
    assert seen["numba"] == min(cores, numba.config.NUMBA_NUM_THREADS)
    assert seen["blas"] == [cores]
    assert after == (min(mine, numba.config.NUMBA_NUM_THREADS), {mine})


@pytest.mark.slow  # importing torch takes seconds
def test_torch_threads_too_in_process_and_in_a_worker(index, tmp_path):
    torch = pytest.importorskip("torch")
    before = torch.get_num_threads()
    torch.set_num_threads(max(1, threads.cores() - 1))
    try:
        assert _seen(_rows(index, tmp_path, toys.ThreadProbe(), 0))["torch"] == threads.cores()
        assert torch.get_num_threads() == max(1, threads.cores() - 1)  # the caller's, again
    finally:
        torch.set_num_threads(before)
    # a worker imports torch with the detector: the toy's plugin module imports it
    folder = tmp_path / "plugins"
    folder.mkdir()
    (folder / "probe.py").write_text(toys.source(toys.ThreadProbe) + "\n\nimport torch\n")
    from slipbench.base import BaseDetector
    from slipbench.engine.registry import Registry

    reg = Registry("detector", BaseDetector, "slipbench.detectors")
    reg.add_folder(folder)
    assert _seen(_rows(index, tmp_path, reg.get("probe")(), 2))["torch"] == threads.share(2)


@pytest.mark.slow
def test_on_dask_sys_exit_fails_cells_threads_are_the_share_and_progress_arrives(
    index, tmp_path, capsys
):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=2, processes=True, dashboard_address=None
    ) as cluster:

        def on_dask(detector, progress=False):
            return evaluate(
                index,
                Run(detector, WindowSize(windows=[50])),
                ResultsStore(tmp_path / type(detector).__name__),
                scheduler=cluster.scheduler_address,
                progress=progress,
            )

        exited = on_dask(toys.ExitsInFit())
        seen = _seen(on_dask(toys.ThreadProbe()))
        capsys.readouterr()
        trained = on_dask(toys.Trainer(epochs=3, seconds=0.3), progress=True)
        file = tmp_path / "scheduler.json"  # as `dask scheduler --scheduler-file` writes it
        file.write_text(f'{{"address": "{cluster.scheduler_address}"}}')
        by_file = evaluate(
            index,
            Run(toys.ThreadProbe(), WindowSize(windows=[50])),
            ResultsStore(tmp_path / "by-file"),
            scheduler=str(file),
            progress=False,
        )
    assert (by_file["status"] == "ok").all()
    assert (exited["status"] == "failed").all() and cells_failed(exited) is not None
    assert exited["reason"].str.contains("raised SystemExit(0) in fit", regex=False).all()
    share = threads.share(2)  # two worker threads on this machine
    assert seen["blas"] == [share] and seen["omp_env"] == str(share)
    assert (trained["status"] == "ok").all()
    assert "trainer: epoch " in capsys.readouterr().err  # worker events reach the bar
