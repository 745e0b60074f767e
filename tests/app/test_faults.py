"""Faults a user meets, each reproduced and shown handled: a clear message, the documented exit
code, intact results. (Storage faults: test_store_faults.py; dead workers and time limits:
test_runner.py; corrupt datasets: test_reader_properties.py.)"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pandas as pd
import psutil
import pytest
import toys

# plugin file stem -> (toy, what the failed cells must say)
CASES = {
    "nan_scores": (toys.NanScores, "non-finite scores"),
    "big_scores": (toys.BigScores, "scores outside [0, 1]"),
    "short_scores": (toys.ShortScores, "scores of shape"),
    "usage_in_fit": (toys.UsageInFit, "UsageError: bad day"),
    "exits_in_fit": (toys.ExitsInFit, "raised SystemExit(0) in fit"),  # exited 0, nothing written
}


@pytest.fixture(scope="module")
def plugins(tmp_path_factory):
    folder = tmp_path_factory.mktemp("plugins")
    for stem, (toy, _) in CASES.items():
        (folder / f"{stem}.py").write_text(toys.source(toy))
    (folder / "broken.py").write_text("import no_such_module_slipbench\n")
    return folder


@pytest.fixture(scope="module")
def one_unit(small_path, tmp_path_factory):
    from slipbench.data.read import read_dataset
    from slipbench.data.write import write_dataset

    ds = read_dataset(small_path)
    keep = ds.recordings["sensor_type"].eq("OptoForce20") & ds.recordings["sensor_instance"].eq(
        "index"
    )
    rec = ds.recordings[keep]
    ids = set(rec["recording_id"])
    return write_dataset(
        tmp_path_factory.mktemp("data") / "unit",
        rec,
        {k: v for k, v in ds.samples.items() if k in ids},
        {k: v for k, v in ds.slip_labels.items() if k in ids} or None,
    )


@pytest.mark.slow
@pytest.mark.parametrize("stem", list(CASES))
def test_a_detector_that_returns_garbage_fails_its_cells_with_the_reason(
    stem, plugins, one_unit, tmp_path, cli
):
    out = tmp_path / "out"
    code, text, err = cli(
        [
            "evaluate",
            "--detector",
            stem.replace("_", "-"),
            "--protocol",
            "window-size",
            "--dataset",
            str(one_unit),
            "--plugins",
            str(plugins),
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert code == 4, err
    assert CASES[stem][1] in err and f"detector '{stem.replace('_', '-')}'" in err
    rows = pd.read_parquet(out / "results.parquet")
    assert (rows["status"] == "failed").all() and rows["reason"].str.contains(
        CASES[stem][1], regex=False
    ).all()
    assert not (out / "predictions").exists() or not any(
        (out / "predictions").iterdir()
    )  # no garbage stored
    code, text, _ = cli(["report", str(out)])  # a results set where every cell failed still reports
    assert code == 0 and "failed" in text


@pytest.mark.slow
def test_all_detectors_run_past_a_broken_plugin_and_exit_3(plugins, one_unit, tmp_path, cli):
    code, _, err = cli(
        [
            "evaluate",
            "--detector",
            "all",
            "--protocol",
            "window-size",
            "--dataset",
            str(one_unit),
            "--plugins",
            str(plugins),
            "--out",
            str(tmp_path / "out"),
            "--quiet",
            "--protocol-param",
            "windows=[50]",
            "--param",
            "max_epochs=1",
        ]
    )
    assert code == 3 and "detector 'broken'" in err and "the other plugins ran" in err
    rows = pd.read_parquet(tmp_path / "out" / "results.parquet")
    assert {"holweg", "lstm", "bandpass", "nan-scores"} <= set(rows["detector"])
    assert (rows.loc[rows["detector"] == "holweg", "status"] == "ok").all()


@pytest.mark.parametrize(
    "args, words",
    [
        (
            ["--param", "max_epochs=abc"],
            "The 'max_epochs' parameter of LSTM must be an int in [1, 100000]",
        ),
        (["--param", "learning_rates=[0.1,-1]"], "The 'learning_rates' parameter of LSTM must be"),
        (["--param", "nope=1"], "no selected detector takes the parameter 'nope'"),
        (["--protocol-param", "windows=abc"], "The 'windows' parameter of WindowSize must be"),
        (["--seed", "-1"], "-1 is not in the range 0<=x<=4294967295"),
        (["--seed", "99999999999999999999"], "is not in the range"),
        (["--scale", "-1"], "is not in (0, 10]"),
        (["--scale", "nan"], "is not in (0, 10]"),
        (["--scale", "1e9"], "is not in (0, 10]"),
    ],
)
def test_bad_options_are_refused_before_any_work(args, words, tmp_path, cli):
    code, _, err = cli(
        [
            "evaluate",
            "--detector",
            "lstm",
            "--protocol",
            "window-size",
            "--out",
            str(tmp_path / "o"),
            *args,
        ]
    )
    assert code == 2 and words in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()  # nothing started, nothing written


def _slipbench(args: list[str], cwd) -> int:
    """A command in a new process, run outside the source tree (so `slipbench` is the installed one)."""
    import subprocess
    import sys

    code = "import sys; from slipbench.app.cli import main; main(sys.argv[1:])"
    return subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=cwd
    ).returncode


@pytest.mark.slow
def test_a_changed_plugin_is_rerun_not_served_from_the_cache(plugins, one_unit, tmp_path):
    folder = tmp_path / "p"
    folder.mkdir()
    source = toys.source(toys.Energy)
    (folder / "energy.py").write_text(source)
    args = [
        "evaluate",
        "--detector",
        "energy",
        "--protocol",
        "window-size",
        "--dataset",
        str(one_unit),
        "--plugins",
        str(folder),
        "--out",
        str(tmp_path / "out"),
        "--quiet",
        "--protocol-param",
        "windows=[25,50]",
    ]
    assert _slipbench(args, tmp_path) == 0
    first = pd.read_parquet(tmp_path / "out" / "results.parquet")
    (folder / "energy.py").write_text(
        source.replace("> self.cut_", "< self.cut_")
    )  # the plugin's code changed
    assert _slipbench(args, tmp_path) == 0
    rows = pd.read_parquet(tmp_path / "out" / "results.parquet")
    assert len(rows) == 2 * len(first)  # the old cells stay, the new code's cells are new
    new = rows[~rows["key"].isin(first["key"])]
    assert len(new) == len(first)
    assert not set(new["accuracy"].round(6)) & set(first["accuracy"].round(6))


@pytest.mark.slow
def test_a_changed_helper_module_of_a_plugin_is_rerun(one_unit, tmp_path):
    """The issue's case: a folder plugin imports a helper beside it; the helper changes, the
    plugin file does not; the cells are computed anew with the new numbers."""
    folder = tmp_path / "p"
    folder.mkdir()
    source = toys.source(toys.Energy).replace("> self.cut_", "> SIGN * self.cut_")
    (folder / "energy.py").write_text(source + "\nfrom faults_helper import SIGN\n")
    (folder / "faults_helper.py").write_text("SIGN = 1\n")
    args = ["evaluate", "--detector", "energy", "--protocol", "window-size"]
    args += ["--dataset", str(one_unit), "--plugins", str(folder), "--out", str(tmp_path / "out")]
    args += ["--quiet", "--protocol-param", "windows=[25]"]
    assert _slipbench(args, tmp_path) == 0
    first = pd.read_parquet(tmp_path / "out" / "results.parquet")
    (folder / "faults_helper.py").write_text("SIGN = -1\n")
    assert _slipbench(args, tmp_path) == 0
    rows = pd.read_parquet(tmp_path / "out" / "results.parquet")
    new = rows[~rows["key"].isin(first["key"])]
    assert len(new) == len(first) > 0
    assert not set(new["accuracy"].round(6)) & set(first["accuracy"].round(6))


@pytest.mark.slow
def test_report_refuses_the_same_results_twice(tmp_path, one_unit, cli):
    out = tmp_path / "out"
    assert (
        cli(
            [
                "evaluate",
                "--detector",
                "holweg",
                "--protocol",
                "window-size",
                "--dataset",
                str(one_unit),
                "--out",
                str(out),
                "--quiet",
                "--protocol-param",
                "windows=[50]",
            ]
        )[0]
        == 0
    )
    code, _, err = cli(["report", str(out), str(out)])
    assert (
        code == 2 and "appear more than once" in err and "the same results were given twice" in err
    )


def test_messages_never_show_numpy_reprs(tmp_path):
    import numpy as np

    from slipbench.data.write import write_dataset
    from slipbench.errors import DataError

    rec = pd.DataFrame(
        [
            dict(
                recording_id=f"r{i}",
                sensor_type="T",
                sensor_instance="a",
                scenario=sc,
                material="m",
                speed_mm_s=25.0,
                sampling_rate_hz=rate,
                channels=("c",),
                units=("u",),
                source="x",
            )
            for i, (sc, rate) in enumerate([("slip", 59.738499926), ("press", 75.0)])
        ]
    )
    samples = {f"r{i}": np.random.default_rng(i).normal(size=(300, 1)) for i in range(2)}
    with pytest.raises(DataError) as info:
        write_dataset(tmp_path / "d", rec, samples)
    import re

    assert not re.search(
        r"np\.(float|int|str)", str(info.value)
    ) and "59.738499926 Hz in recording(s) 'r0'" in str(info.value)


@pytest.fixture(scope="module")
def trainer(tmp_path_factory):
    folder = tmp_path_factory.mktemp("trainer")
    (folder / "trainer.py").write_text(toys.source(toys.Trainer))
    return folder


def _training(unit, trainer, out, *args: str) -> list[str]:
    return [
        *("evaluate", "--detector", "trainer", "--protocol", "window-size"),
        *("--dataset", str(unit), "--plugins", str(trainer), "--out", str(out), *args),
    ]


@pytest.mark.parametrize("jobs", ["0", pytest.param("1", marks=pytest.mark.slow)])
def test_the_bar_shows_the_progress_a_model_reports(unit, trainer, tmp_path, cli, jobs):
    two_epochs = ["--param", "epochs=2", "--param", "seconds=0.26", "--jobs", jobs]
    args = _training(unit, trainer, tmp_path / "o", "--protocol-param", "windows=[50]", *two_epochs)
    code, _, err = cli(args)
    assert code == 0, err
    assert "trainer: epoch 1/2, loss 1" in err and "trainer: epoch 2/2, loss 0.5" in err
    code, _, err = cli([*args, "--force", "--quiet"])
    assert code == 0 and "epoch" not in err


@pytest.mark.parametrize("signum, code", [(signal.SIGTERM, 143), (signal.SIGHUP, 129)])
def test_sigterm_and_sighup_end_a_command_as_ctrl_c_does(monkeypatch, cli, signum, code):
    from slipbench.engine import registry

    def signalled(self):
        os.kill(os.getpid(), signum)
        time.sleep(5)  # the handler interrupts this at once

    before = signal.getsignal(signum)
    monkeypatch.setattr(registry.Registry, "names", signalled)
    code_, _, err = cli(["list"])
    assert code_ == code and f"interrupted by {signal.Signals(signum).name}; finished" in err
    assert signal.getsignal(signum) == before  # the caller's handler is back


# signal, sent to the whole process group (a terminal's Ctrl-C) or to the run alone (`timeout`,
# `kill`, a supervisor), jobs, exit code
STOPPING = [
    pytest.param(signal.SIGTERM, False, "2", 143, id="SIGTERM-2-workers"),
    pytest.param(signal.SIGTERM, True, "0", 143, id="SIGTERM-group-in-process"),
    pytest.param(signal.SIGHUP, False, "1", 129, id="SIGHUP-1-worker"),
    pytest.param(signal.SIGINT, True, "1", 130, id="Ctrl-C-1-worker"),
]


@pytest.mark.slow
@pytest.mark.parametrize("signum, group, jobs, code", STOPPING)
def test_a_signal_stops_the_run_within_5_s_and_keeps_finished_cells(
    unit, trainer, tmp_path, signum, group, jobs, code
):
    """Window 25 trains in one epoch, window 50 for an hour: the signal comes while it trains."""
    out = tmp_path / "o"
    args = _training(unit, trainer, out, "--protocol-param", "windows=[25,50]", "--jobs", jobs)
    hour = ["--param", "long_window=50", "--param", "epochs=36000", "--param", "seconds=0.1"]
    run = subprocess.Popen(
        [sys.executable, "-m", "slipbench.app.cli", *args, *hour],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
        start_new_session=True,  # its own group: a signal to the group reaches no test process
    )
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline and not list(out.glob("cells/*.parquet")):
        time.sleep(0.1)
    time.sleep(1.0)  # window 50 is training
    family = psutil.Process(run.pid).children(recursive=True)
    assert run.poll() is None and (jobs == "0" or family), "the run should still be training"
    sent = time.monotonic()
    (os.killpg if group else os.kill)(run.pid, signum)
    _, err = run.communicate(timeout=30)
    took = time.monotonic() - sent
    assert run.returncode == code and took < 5.0, (took, err)
    assert "finished cells are kept" in err and "run the same command again" in err
    _, alive = psutil.wait_procs(family, timeout=3)
    assert not [p for p in alive if _running(p)], "a process of the run survived it"
    rows = pd.read_parquet(out / "results.parquet")
    # the cell in flight was cancelled, not recorded: the same command runs it again
    assert list(rows["window"]) == [25] and list(rows["status"]) == ["ok"]


def _running(proc: psutil.Process) -> bool:
    try:
        return proc.status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False
