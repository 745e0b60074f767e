"""Input no machine can honour, refused at once with one line and exit 2 (never an internal
error, exit 70): a destination the system refuses ("/proc/self/x"), a file or value nested
thousands deep, a scheduler that names nothing, sizes beyond what a machine can plan (repeats,
jobs, windows). Each case names a dataset that does not exist: the refusal comes first, before
anything is read or written."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from slipbench.engine import threads
from slipbench.engine.limits import JOBS_PER_CORE, SCHEDULERS, scheduler_problem
from slipbench.vocabulary import MAX_WINDOW

EVALUATE = ["evaluate", "--detector", "holweg", "--protocol", "window-size"]
DEEP = "[" * 3000 + "]" * 3000
MOST = JOBS_PER_CORE * threads.cores()

CASES = {
    "an --out no file can be made in": (["--out", "/proc/self/x"], "/proc/self/x: no file can"),
    "repeats by the billion": (["--repeats", "1000000000"], "--repeats 1000000000: at most 1000"),
    "seeds past the largest": (["--seed", "4294967295", "--repeats", "2"], "pass 4294967295"),
    "jobs beyond the machine": (["--jobs", str(MOST + 1)], f"--jobs {MOST + 1}: more than {MOST}"),
    "a scheduler that is no address": (
        ["--scheduler", "submitit-locl"],
        "--scheduler 'submitit-locl': not a dask scheduler's address",
    ),
    "a scheduler of a scheme dask lacks": (
        ["--scheduler", "http://example.org:80"],
        "dask knows no scheme 'http'",
    ),
    "a port that is no number": (["--scheduler", "host:port"], "--scheduler 'host:port': not a"),
    "a parameter nested thousands deep": (["--param", f"x={DEEP}"], "--param x: nested too deep"),
    "a window longer than a plan takes": (
        ["--protocol-param", f"windows=[{10**20}]"],
        f"in [5, {MAX_WINDOW}]",
    ),
    "a window of 1e300 ms": (["--protocol-param", 'windows=["1e300ms"]'], "(at most 3600000"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_absurd_options_are_refused_at_once_with_one_line(case, tmp_path, cli):
    args, said = CASES[case]
    out = [] if "--out" in args else ["--out", str(tmp_path / "out")]
    code, stdout, err = cli(
        [*EVALUATE, "--dataset", str(tmp_path / "no-such-dataset"), *out, *args]
    )
    assert code == 2, err
    assert err.startswith("error: ") and len(err.strip().splitlines()) == 1, err
    assert said in err and "no-such-dataset" not in err  # refused before the data is read
    assert not (tmp_path / "out").exists() and stdout == ""


RUN_FILES = {
    "out = /proc/self/x": ('[benchmark]\nout = "/proc/self/x"\n', "/proc/self/x: no file can"),
    "a table 3000 deep": (f"[run]\nplugins = {DEEP}\n", "nested too deeply to read"),
    "an inline table 3000 deep": ("x = " + "{a=" * 3000 + "1" + "}" * 3000, "nested too deeply"),
    "repeats by the billion": ("[run]\nrepeats = 1000000000\n", "[run] repeats: repeats 100"),
    "jobs beyond the machine": (f"[run]\njobs = {MOST + 1}\n", f"[run] jobs: jobs {MOST + 1}"),
    "a scheduler that is no address": (
        '[run]\nscheduler = "submitit-locl"\n',
        "[run] scheduler: scheduler 'submitit-locl': not a dask",
    ),
}


@pytest.mark.parametrize("case", list(RUN_FILES))
def test_absurd_run_files_are_refused_at_once_with_one_line(case, tmp_path, cli):
    text, said = RUN_FILES[case]
    bench = tmp_path / "bench.toml"
    plugins = "[detectors.holweg]\n[protocols.window-size]\n"
    bench.write_text(f'{text}\n[dataset]\npath = "missing"\n{plugins}')
    code, _, err = cli(["run", str(bench)])
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"error: {bench}") or err.startswith("error: /proc/self/x"), err
    assert said in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bench.toml"]


def test_a_scheduler_is_an_address_a_file_or_a_known_name(tmp_path, monkeypatch):
    """What dask takes passes (the connection is tried when the run starts); the names of
    executors are one tuple, which a new executor extends."""
    for address in ("127.0.0.1:8786", "tcp://scheduler.lab:8786", "tls://[::1]:8786"):
        assert scheduler_problem(address) is None, address
    file = tmp_path / "scheduler.json"  # as `dask scheduler --scheduler-file` writes it
    file.write_text('{"address": "tcp://127.0.0.1:8786"}')
    assert scheduler_problem(str(file)) is None
    assert scheduler_problem("submitit-local") is None
    assert "nor one of slurm, submitit-local" in str(scheduler_problem("submitit-locl"))
    monkeypatch.setattr("slipbench.engine.limits.SCHEDULERS", (*SCHEDULERS, "mine"))
    assert scheduler_problem("mine") is None


def test_the_python_api_refuses_the_same(small):
    from slipbench.engine.runner import Run, evaluate
    from slipbench.errors import UsageError
    from slipbench.store.results import ResultsStore

    store = ResultsStore(Path(os.devnull))  # never reached
    with pytest.raises(UsageError, match=f"jobs={MOST + 1}: more than {MOST}"):
        evaluate(small, Run("holweg", "window-size"), store, jobs=MOST + 1)
    with pytest.raises(UsageError, match="scheduler 'nowhere': not a dask"):
        evaluate(small, Run("holweg", "window-size"), store, scheduler="nowhere")
