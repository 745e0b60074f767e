"""SLURM job arrays through submitit: the same rows as local workers, a launcher killed and
relaunched, the parameters submitted to (submitit's own mocked) SLURM, and array tasks that
end badly."""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import platform
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import psutil
import pytest
import toys

from slipbench.engine import slurm
from slipbench.engine.runner import Run, evaluate
from slipbench.errors import UsageError
from slipbench.protocols.window_size import WindowSize
from slipbench.store.results import ResultsStore, read_results

pytest.importorskip("submitit")

#: what a row measures of the machine and the moment rather than of the cell
MEASURED = {
    "run_id",
    "finished_at",
    "train_s",
    "train_us_per_sample",
    "peak_mem_mb",
    "infer_us_per_window",
    "test_s",
    "stream_s",
    "compute_ms_per_hop",
    "realtime",
}


def _rows(folder: Path) -> pd.DataFrame:
    rows = read_results(folder)
    return rows.drop(columns=[c for c in MEASURED if c in rows]).set_index("key").sort_index()


def _cli(*argv: str, cwd: Path) -> subprocess.CompletedProcess:
    # from outside the source tree, so that `slipbench` is the installed package
    return subprocess.run(
        [sys.executable, "-m", "slipbench.app.cli", *argv], capture_output=True, text=True, cwd=cwd
    )


@pytest.mark.slow  # every built-in detector twice: about a minute on 2 cores
def test_submitit_local_gives_the_rows_of_local_workers(tmp_path):
    common = ["evaluate", "--detector", "all", "--protocol", "window-size", "--scale", "0.01"]
    local = _cli(*common, "--jobs", "2", "--out", str(tmp_path / "local"), cwd=tmp_path)
    assert local.returncode == 0, local.stderr
    arrays = _cli(
        *common,
        "--scheduler",
        "submitit-local",
        "--slurm",
        "tasks=2",
        "--cell-timeout",
        "900",
        "--out",
        str(tmp_path / "arrays"),
        cwd=tmp_path,
    )
    assert arrays.returncode == 0, arrays.stderr
    # minirocket needs aeon, not installed here: both runs leave it out, saying why
    assert "skipped detector 'minirocket'" in local.stderr + arrays.stderr or _has_aeon()
    a, b = _rows(tmp_path / "local"), _rows(tmp_path / "arrays")
    assert set(a["detector"]) >= {"holweg", "bandpass", "wavelet-svm", "features", "lstm", "tcn"}
    assert (a["status"] == "ok").all()
    pd.testing.assert_frame_equal(a, b[a.columns])
    # the array tasks wrote the cells; their submitit files are kept beside the results
    assert list((tmp_path / "arrays" / "slurm").glob("*_submitted.pkl"))


def _has_aeon() -> bool:
    try:
        import aeon  # noqa: F401
    except ImportError:
        return False
    return True


@pytest.mark.slow  # three runs of 48 slow cells
def test_a_killed_launcher_resumes_with_the_rows_of_a_local_run(small_path, tmp_path):
    """SIGKILL the launcher and its array tasks mid-way: the same command, run again,
    computes what is missing; the rows are those of a local run."""
    plugins = tmp_path / "plugins"
    plugins.mkdir()
    (plugins / "slow.py").write_text(toys.source(toys.Slow))
    common = ["evaluate", "--detector", "slow", "--protocol", "window-size"]
    common += ["--dataset", str(small_path), "--plugins", str(plugins), "--quiet"]
    out = tmp_path / "arrays"
    argv = [*common, "--scheduler", "submitit-local", "--slurm", "tasks=3", "--out", str(out)]
    argv += ["--cell-timeout", "60"]
    launcher = subprocess.Popen(
        [sys.executable, "-m", "slipbench.app.cli", *argv],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
    )
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and len(list((out / "cells").glob("*.parquet"))) < 5:
        time.sleep(0.05)
    # the launcher and its array tasks at once, as a lost node takes both
    procs = [psutil.Process(launcher.pid), *psutil.Process(launcher.pid).children(recursive=True)]
    for proc in procs:
        proc.send_signal(signal.SIGKILL)
    psutil.wait_procs(procs, timeout=60)
    _, err = launcher.communicate()
    assert 5 <= len(list((out / "cells").glob("*.parquet"))) < 48, err
    again = _cli(*argv, cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    local = _cli(*common, "--jobs", "2", "--out", str(tmp_path / "local"), cwd=tmp_path)
    assert local.returncode == 0, local.stderr
    a, b = _rows(tmp_path / "local"), _rows(out)
    assert len(a) == 48 and (b["status"] == "ok").all()
    pd.testing.assert_frame_equal(a, b[a.columns])


@pytest.fixture
def mocked(monkeypatch):
    """submitit's own mocked SLURM (sbatch, sacct, scancel): each look at the array runs its
    tasks, each in a process of its own as a node would (submitit's entry point, with the
    environment SLURM gives an array task), and they end COMPLETED; a job id in
    ``mock.ended`` ends with that state instead, without running (every one where
    ``mock.none_runs``: TIMEOUT)."""
    from submitit.slurm.slurm import SlurmJob
    from submitit.slurm.test_slurm import mocked_slurm

    ended: dict[str, str] = {}
    ran: set[str] = set()
    platform.platform(), platform.processor()  # asked once, before subprocess is mocked
    run = subprocess.run  # the mock replaces check_output and check_call only
    with mocked_slurm() as mock:

        def look(_seconds: float) -> None:
            for pickled in sorted(Path(mock.folder).glob("*_submitted.pkl")):
                job_id = pickled.name.split("_submitted")[0]
                if job_id in ran:
                    continue
                ran.add(job_id)
                if job_id in ended or mock.none_runs:
                    mock.set_job_state(job_id, ended.get(job_id, "TIMEOUT"))
                    continue
                array, _, task = job_id.partition("_")
                env = os.environ | {
                    "SUBMITIT_EXECUTOR": "slurm",
                    "SLURM_JOB_ID": job_id,
                    "SLURM_ARRAY_JOB_ID": array,
                    "SLURM_ARRAY_TASK_ID": task,
                }
                done = run(
                    [sys.executable, "-m", "submitit.core._submit", str(pickled.parent)],
                    env=env,
                    # from the job's folder, as a node would: `-m` puts the working folder first
                    # on sys.path, and a source tree there would shadow the installed package
                    cwd=pickled.parent,
                    capture_output=True,
                    text=True,
                )
                mock.set_job_state(job_id, "COMPLETED" if done.returncode == 0 else "FAILED")
            SlurmJob.watcher.update()

        monkeypatch.setattr(slurm, "_pause", look)
        mock.ended, mock.none_runs = ended, False
        yield mock


def _sbatch(path: Path) -> list[str]:
    """The lines of a submission script that ask SLURM for something, or set the task up."""
    return [
        line.strip()
        for line in path.read_text().splitlines()
        if line.startswith("#SBATCH") or line.startswith("module")
    ]


def _index(small):
    from datagen import subset

    rec = small.recordings
    return subset(small, rec["sensor_type"].eq("Nano17") & rec["sensor_instance"].eq("index"))


@pytest.fixture
def energy(tmp_path):
    """The toy energy detector from a plugin folder, as a lab's own detector reaches the
    nodes: its file, imported again there."""
    from slipbench.engine import registry

    folder = tmp_path / "plugins"
    folder.mkdir()
    (folder / "energy.py").write_text(toys.source(toys.Energy))
    registry.add_plugin_folder(folder)
    return "energy"


RESOURCES = {
    "partition": "cpu",
    "cpus_per_task": 2,
    "mem_gb": 6,
    "array_parallelism": 3,
    "tasks": 4,
    "account": "lab",
    "setup": ["module load python"],
    "holweg": {"partition": "gpu", "gpus_per_node": 1, "time": 30},
}


def test_the_resources_reach_sbatch(small, tmp_path, mocked, energy):
    """What each job array asks SLURM for, read from the scripts submitit gave sbatch; every
    task ends at its time limit here, and its cells say so."""
    folder = tmp_path / "slurm"
    mocked.folder, mocked.none_runs = folder, True
    res = slurm.resources({**RESOURCES, "folder": str(folder)})
    runs = [Run("holweg", WindowSize(windows=[50, 100])), Run(energy, WindowSize())]
    rows = evaluate(
        _index(small),
        runs,
        ResultsStore(tmp_path / "out"),
        scheduler="slurm",
        slurm=res,
        cell_timeout=100,
        progress=False,
    )
    holweg, energy_ = (sorted(_sbatch(path)) for path in sorted(folder.glob("*_submission.sh")))
    # holweg's own array: 2 models in 2 tasks, on the GPU partition for its stated 30 minutes
    assert {
        "#SBATCH --partition=gpu",
        "#SBATCH --gpus-per-node=1",
        "#SBATCH --time=30",
        "#SBATCH --array=0-1%2",  # submitit caps the parallelism at the array's size
        "#SBATCH --job-name=slipbench-holweg",
    } <= set(holweg), holweg
    # energy's: 6 models in 4 tasks; the cell limit x 2 models on 2 cores, plus the margin
    minutes = slurm.time_limit(res, [100.0, 100.0], 2)
    assert minutes == 15
    assert {
        f"#SBATCH --time={minutes}",
        "#SBATCH --array=0-3%3",
        "#SBATCH --partition=cpu",
        "#SBATCH --cpus-per-task=2",
        "#SBATCH --mem=6GB",
        "#SBATCH --account=lab",
        "module load python",
    } <= set(energy_), energy_
    assert "#SBATCH --gpus-per-node=1" not in energy_
    assert (rows["status"] == "timeout").all()
    assert (
        rows.loc[rows["detector"] == "holweg", "reason"]
        .str.fullmatch(
            r"array task 12_[01] reached its time limit \(30 min\) before this cell finished"
        )
        .all()
    )


@pytest.mark.slow  # six array tasks, each a process importing slipbench: a minute
def test_the_array_tasks_write_the_rows_of_a_local_run(small, tmp_path, mocked, energy):
    folder = tmp_path / "slurm"
    mocked.folder = folder
    res = slurm.resources({**RESOURCES, "folder": str(folder)})
    runs = [Run("holweg", WindowSize(windows=[50, 100])), Run(energy, WindowSize())]
    store = ResultsStore(tmp_path / "out")
    rows = evaluate(
        _index(small), runs, store, scheduler="slurm", slurm=res, cell_timeout=100, progress=False
    )
    assert rows["status"].tolist() == ["ok"] * 8, rows["reason"].tolist()
    # the array tasks wrote the rows; the launcher gathered them, the same as a local run's
    local = evaluate(_index(small), runs, ResultsStore(tmp_path / "local"), progress=False)
    keep = [c for c in local.columns if c not in MEASURED]
    pd.testing.assert_frame_equal(
        local[keep].set_index("key").sort_index(), rows[keep].set_index("key").sort_index()
    )


@pytest.mark.slow  # array tasks run as processes
def test_an_array_task_past_its_time_limit_fails_its_cells_and_a_rerun_resumes(
    small, tmp_path, mocked, energy
):
    folder = tmp_path / "slurm"
    mocked.folder = folder
    mocked.ended["12_1"] = "TIMEOUT"  # the second task of the first array
    res = slurm.Resources(tasks=2, folder=str(folder), time=20)
    run = Run(energy, WindowSize())
    store = ResultsStore(tmp_path / "out")
    rows = evaluate(_index(small), run, store, scheduler="slurm", slurm=res, progress=False)
    timed_out = rows[rows["status"] == "timeout"]
    assert len(timed_out) == 3 and (rows["status"] == "ok").sum() == 3
    assert set(timed_out["reason"]) == {
        "array task 12_1 reached its time limit (20 min) before this cell finished"
    }
    again = evaluate(_index(small), run, store, scheduler="slurm", slurm=res, progress=False)
    assert (again["status"] == "ok").all()
    # the cells already done were not submitted again: the second array holds the three
    submitted = json.loads((folder / "submitted.json").read_text())["slurm"]
    again_keys = [k for job, keys in submitted.items() if job.startswith("13_") for k in keys]
    assert sorted(again_keys) == sorted(timed_out["key"])


@pytest.mark.slow  # array tasks run as processes
def test_a_relaunch_adopts_the_array_tasks_still_queued(small, tmp_path, mocked, energy):
    """A launcher that died left its array queued: the next launch waits for those tasks
    rather than submitting their cells again."""
    folder = tmp_path / "slurm"
    mocked.folder = folder
    res = slurm.Resources(tasks=2, folder=str(folder), time=20)
    run = Run(energy, WindowSize())
    index = _index(small)
    with pytest.raises(KeyboardInterrupt):  # the launcher stops before any task ran
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(slurm, "_pause", _interrupt)
            evaluate(index, run, ResultsStore(tmp_path / "out"), scheduler="slurm", slurm=res)
    # Ctrl-C cancels the array; a killed launcher would not: put it back in the queue
    mocked.set_job_state("12", "PENDING", array=2)
    rows = evaluate(
        index, run, ResultsStore(tmp_path / "out"), scheduler="slurm", slurm=res, progress=False
    )
    assert (rows["status"] == "ok").all() and len(rows) == 6
    assert len(list(folder.glob("*_submission.sh"))) == 1  # nothing submitted a second time


def _interrupt(_seconds: float) -> None:
    raise KeyboardInterrupt


def test_an_array_needs_a_time_limit(small, tmp_path, mocked):
    mocked.folder = tmp_path / "slurm"
    res = slurm.Resources(folder=str(tmp_path / "slurm"))
    with pytest.raises(UsageError, match="need a time limit: give \\[slurm\\] time"):
        evaluate(
            _index(small),
            Run("holweg", WindowSize()),
            ResultsStore(tmp_path / "out"),
            scheduler="slurm",
            slurm=res,
            progress=False,
        )


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"time": 0}, "[slurm] time: must be minutes an array task may run, an int > 0, got 0"),
        ({"cpus": 4}, "[slurm] cpus: unknown key; [slurm] takes partition, account"),
        ({"mem_gb": "8G"}, "[slurm] mem_gb: must be memory per array task in GB, > 0"),
        ({"lstm": {"tasks": 3}}, "[slurm] lstm.tasks: unknown key; a detector's takes"),
        ({"nope": {"time": 3}}, "[slurm] nope: not a detector of this run (lstm)"),
        ({"setup": ["ok", 3]}, "[slurm] setup: must be a list of shell lines"),
    ],
)
def test_a_bad_slurm_table_names_its_key(table, message):
    with pytest.raises(UsageError) as err:
        slurm.resources(table, ("lstm",))
    assert str(err.value).startswith(message)


def test_options_over_a_table():
    table = slurm.from_options(
        ("time=120", "lstm.gpus_per_node=1", 'setup=["module load cuda"]', "partition=gpu"),
        {"partition": "cpu", "lstm": {"cpus_per_task": 8}},
    )
    res = slurm.resources(table, ("lstm", "holweg"))
    assert (res.time, res.partition, res.setup) == (120, "gpu", ("module load cuda",))
    lstm = res.of("lstm")
    assert (lstm.gpus_per_node, lstm.cpus_per_task, res.of("holweg").gpus_per_node) == (1, 8, 0)
    with pytest.raises(UsageError, match="expected KEY=VALUE"):
        slurm.from_options(("time",))


def test_tasks_are_dealt_whole_longest_first():
    class T:
        def __init__(self, models: int, detector: str) -> None:
            self.models, self.detector = models, detector
            self.first = type("F", (), {"run": type("R", (), {"detector_name": detector})})

    tasks = [T(m, "lstm") for m in (1, 5, 2, 2)] + [T(1, "holweg")]
    shards = slurm.dealt(tasks, slurm.Resources(tasks=2), lambda t: float(t.models))
    assert [(s.detector, s.weight) for s in shards] == [
        ("lstm", 5.0),
        ("lstm", 5.0),
        ("holweg", 1.0),
    ]


class _Planted:
    """A pickle whose loading leaves ``marker``: what someone with write access to a shared
    results folder could put there."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (open, (str(self.marker), "w"))


def test_a_planted_result_pickle_in_the_slurm_folder_never_runs(small, tmp_path, monkeypatch):
    """A results folder whose ``slurm/submitted.json`` lists an array task that ``sacct``
    (a fake one, on PATH) calls running, beside a planted ``*_result.pkl``: the relaunch adopts
    the task, and when it ends reads its cells, never the pickle; the cells it did not write
    fail, saying so."""
    from submitit.slurm.slurm import SlurmJob

    run = Run("holweg", WindowSize(windows=[50, 100]))
    keys = evaluate(_index(small), run, ResultsStore(tmp_path / "local"), progress=False)["key"]
    out, marker = tmp_path / "out", tmp_path / "marker"
    folder = out / "slurm"
    folder.mkdir(parents=True)
    (folder / "submitted.json").write_text(json.dumps({"slurm": {"99_0": list(keys)}}))
    for name in ("99_0_0_result.pkl", "99_0_result.pkl", "99_result.pkl"):
        (folder / name).write_bytes(pickle.dumps(_Planted(marker)))
    state = tmp_path / "state"
    state.write_text("RUNNING")
    bin_ = tmp_path / "bin"
    bin_.mkdir()
    sacct = bin_ / "sacct"
    sacct.write_text(f'#!/bin/sh\necho "JobID|State|NodeList"\necho "99_0|$(cat {state})|n1"\n')
    sacct.chmod(0o755)
    monkeypatch.setenv("PATH", f"{bin_}{os.pathsep}{os.environ['PATH']}")
    monkeypatch.setattr(slurm, "SHARED_FS_S", 0.0)

    def ends(_seconds: float) -> None:
        state.write_text("COMPLETED")
        SlurmJob.watcher.update()

    monkeypatch.setattr(slurm, "_pause", ends)
    rows = evaluate(
        _index(small), run, ResultsStore(out), scheduler="slurm", cell_timeout=60, progress=False
    )
    assert not marker.exists()
    assert sorted(rows["key"]) == sorted(keys) and (rows["status"] == "failed").all()
    assert set(rows["reason"]) == {
        "array task 99_0 ended without this cell in the results folder: is it on a file "
        "system the nodes share?"
    }


def test_an_array_task_never_unpickles_a_dataset_its_launcher_did_not_write(tmp_path):
    from slipbench.engine.runner import _unpickled
    from slipbench.errors import DataError

    marker, path = tmp_path / "marker", tmp_path / "dataset-abc.pkl"
    path.write_bytes(pickle.dumps(_Planted(marker)))
    with pytest.raises(DataError, match="not the dataset its launcher wrote .*; not unpickled"):
        _unpickled(path, hashlib.sha256(b"what the launcher wrote").hexdigest())
    assert not marker.exists()
