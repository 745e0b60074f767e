"""The command line, end to end: datasets, evaluation, and clear errors with exit code 2."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys

import pandas as pd
import pyarrow.parquet as pq
import pytest
from fsfaults import read_only

from slipbench.data.schema import SAMPLES_FILE


@pytest.mark.slow
def test_dataset_commands(tmp_path, cli):
    path = tmp_path / "ds"
    code, out, _ = cli(["dataset", "synth", str(path), "--scale", "0.01", "--seed", "3"])
    assert code == 0 and path.is_dir()
    code, out, _ = cli(["dataset", "validate", str(path)])
    assert code == 0 and "valid slipbench dataset v1" in out
    code, out, _ = cli(["dataset", "info", str(path)])
    assert code == 0 and "free-space" in out and "neoprene" in out and "total:" in out


def test_corrupted_copy_is_refused(small_path, tmp_path, cli):
    broken = tmp_path / "broken"
    shutil.copytree(small_path, broken)
    table = pq.read_table(broken / SAMPLES_FILE)
    pq.write_table(
        table.drop_columns(["values"]).replace_schema_metadata(table.schema.metadata),
        broken / SAMPLES_FILE,
    )
    code, _, err = cli(["dataset", "validate", str(broken)])
    assert code == 2
    assert "samples.parquet: column 'values': required column missing" in err
    assert "Traceback" not in err


@pytest.mark.slow
def test_evaluate_writes_results_and_prints_the_table(small_path, tmp_path, cli):
    out = tmp_path / "res"
    argv = [
        "evaluate",
        "--detector",
        "holweg",
        "--protocol",
        "window-size",
        "--dataset",
        str(small_path),
        "--out",
        str(out),
        "--quiet",
    ]
    code, text, _ = cli(argv)
    assert code == 0
    assert "Sensor |" in text and "Finger |" in text and "Biotac SP" in text and "Little" in text
    rows = pq.read_table(out / "results.parquet").to_pandas()
    assert len(rows) == 48 and (rows["status"] == "ok").all()
    assert set(rows["window"]) == {5, 10, 25, 50, 100, 200}
    for column in (
        "accuracy_lo",
        "tp_rate_hi",
        "train_us_per_sample",
        "infer_us_per_window",
        "dataset_fingerprint",
        "slipbench_version",
        "detector_params",
        "seed",
    ):
        assert rows[column].notna().all(), column
    assert (rows["accuracy_lo"] <= rows["accuracy"]).all() and (
        rows["accuracy"] <= rows["accuracy_hi"]
    ).all()
    # a second run reuses every cell
    before = {p.name: p.stat().st_mtime_ns for p in (out / "cells").iterdir()}
    code, _, _ = cli(argv)
    assert code == 0 and before == {p.name: p.stat().st_mtime_ns for p in (out / "cells").iterdir()}


@pytest.mark.parametrize(
    "argv, message",
    [
        (
            ["evaluate", "--detector", "nope", "--protocol", "window-size"],
            "unknown detector 'nope'; available: ",
        ),
        (
            ["evaluate", "--detector", "holweg", "--protocol", "nope"],
            "unknown protocol 'nope'; available:",
        ),
        (
            [
                "evaluate",
                "--detector",
                "holweg",
                "--protocol",
                "window-size",
                "--param",
                "band=[9,1]",
            ],
            "The 'band' parameter of Holweg",
        ),
        (["dataset", "validate", "/nonexistent/folder"], "not a dataset folder"),
    ],
)
def test_usage_errors_exit_2_without_traceback(argv, message, small_path, tmp_path, cli):
    argv = argv + (
        ["--dataset", str(small_path), "--out", str(tmp_path / "res"), "--quiet"]
        if argv[0] == "evaluate"
        else []
    )
    code, _, err = cli(argv)
    assert code == 2 and message in err and "Traceback" not in err
    assert not (tmp_path / "res" / "results.parquet").exists()


@pytest.mark.slow
def test_window_longer_than_every_recording(tmp_path, cli):
    from slipbench.data.synth import Design, synthesize

    path = synthesize(
        tmp_path / "short", scale=0.0005, seed=0, design=Design(sensors=("BioTacSP",))
    )
    code, _, err = cli(
        [
            "evaluate",
            "--detector",
            "holweg",
            "--protocol",
            "window-size",
            "--dataset",
            str(path),
            "--out",
            str(tmp_path / "res"),
            "--quiet",
        ]
    )
    assert code == 0, (
        err
    )  # the cells that fit run; the others are skipped with the reason, never the run
    rows = pd.read_parquet(tmp_path / "res" / "results.parquet")
    long = rows[rows["window"] >= 100]
    assert (long["status"] == "skipped").all() and (
        rows.loc[rows["window"] < 100, "status"] == "ok"
    ).all()
    assert long["reason"].str.contains("is longer than every recording of BioTacSP").all()


def test_bench_prints_costs(cli):
    code, out, err = cli(
        ["bench", "--detector", "holweg", "--windows", "40", "--length", "20", "--seconds", "0.05"]
    )
    assert code == 0, err
    assert "| holweg" in out and "train_us_per_sample" in out


def test_a_bug_shows_its_traceback_and_says_so(cli, monkeypatch):
    import slipbench.data.read

    def broken(*args, **kwargs):
        raise ZeroDivisionError("a slip of the pen")

    monkeypatch.setattr(slipbench.data.read, "read_dataset", broken)
    code, _, err = cli(["dataset", "validate", "anything"])
    assert (
        code == 70
        and "ZeroDivisionError: a slip of the pen" in err
        and "this is a bug in slipbench" in err
    )


def test_an_environment_fault_that_lost_its_path_says_so(cli, monkeypatch):
    """The last resort for a write that names no file: never `cannot write ?`."""
    import errno

    import slipbench.data.read

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(slipbench.data.read, "read_dataset", full)
    code, _, err = cli(["dataset", "validate", "anything"])
    assert code == 5 and err == (
        "error: no space left on device (ENOSPC), in a write whose path slipbench lost on the "
        "way (a bug in slipbench: please report it with the command)\n"
    )


@pytest.mark.slow
def test_python_m_slipbench_is_the_slipbench_command(cli, tmp_path):
    """`python -m slipbench` runs the same main: the same help, the same errors and exit codes."""

    def module(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run(
            [sys.executable, "-m", "slipbench", *args], capture_output=True, text=True
        )

    shown = module("--help")
    code, out, _ = cli(["--help"])
    assert shown.returncode == code == 0
    assert shown.stdout == out and out.startswith("Usage: slipbench [OPTIONS] COMMAND")
    missing = module("dataset", "validate", str(tmp_path / "nowhere"))
    assert missing.returncode == 2 and "not a dataset folder" in missing.stderr


# ----------------------------------------------------------------------------- destinations
@pytest.fixture
def unwritable(tmp_path):
    """An empty folder this process cannot write."""
    (tmp_path / "ro").mkdir()
    with read_only(tmp_path / "ro") as folder:
        yield folder


# Each command with a destination in the unwritable folder RO (deep: none of its folders exists)
# and inputs that do not exist: the destination is refused first, so no input was read.
WRITERS = {
    "evaluate": ["evaluate", "--detector", "holweg", "--protocol", "window-size"]
    + ["--dataset", "{missing}", "--out", "{dest}"],
    "report --out": ["report", "{missing}", "--out", "{dest}"],
    "report --plots": ["report", "{missing}", "--plots", "{dest}"],
    "report --appendix": ["report", "{missing}", "--appendix", "{dest}"],
    "compare --out": ["compare", "{missing}", "{missing}", "--out", "{dest}"],
    "dataset synth": ["dataset", "synth", "{dest}"],
    "dataset import": ["dataset", "import", "csv", "{missing}", "{dest}", "--config", "{missing}"],
    "dataset rewrite": ["dataset", "rewrite", "{missing}", "{dest}"],
    "dataset fetch": ["dataset", "fetch", "biotacsp-dos", "--url", "http://127.0.0.1:9/"]
    + ["--out", "{dest}"],
    "spectral": ["spectral", "--sensor", "Nano17", "--dataset", "{missing}", "--out", "{dest}"],
    "run": ["run", "{missing}", "--out", "{dest}"],
}


@pytest.mark.parametrize("command", sorted(WRITERS))
def test_an_unwritable_destination_is_refused_before_any_work(command, unwritable, tmp_path, cli):
    dest = unwritable / "new" / "deeper"
    argv = [a.format(missing=tmp_path / "missing", dest=dest) for a in WRITERS[command]]
    code, out, err = cli(argv)
    cause = "read-only file system (EROFS)" if os.geteuid() == 0 else "permission denied (EACCES)"
    assert code == 5, err
    assert err == (
        f"error: cannot write {dest}: {cause}; found before any work (in {unwritable}, where it "
        "would be made); nothing was written\n"
    )
    assert not any(unwritable.iterdir()) and not (tmp_path / "missing").exists()


def test_destinations_decided_late_are_checked_before_any_work(
    unwritable, tmp_path, cli, monkeypatch
):
    """`run` without --out writes to the file's benchmark.out; `dataset fetch` without --out
    to the card's name in the working folder."""
    bench = tmp_path / "bench.toml"
    bench.write_text(
        f'[benchmark]\nout = "{unwritable}/res"\n[dataset]\npath = "{tmp_path / "missing"}"\n'
        "[detectors.holweg]\n[protocols.window-size]\n"
    )
    code, _, err = cli(["run", str(bench)])
    assert code == 5 and err.startswith(f"error: cannot write {unwritable}/res: "), err
    monkeypatch.chdir(unwritable)
    code, _, err = cli(["dataset", "fetch", "biotacsp-dos", "--url", "http://127.0.0.1:9/"])
    assert code == 5 and err.startswith("error: cannot write biotacsp-dos: "), err


def test_a_results_folder_that_holds_cells_is_checked_by_the_run(tmp_path):
    """A read-only results folder passes the up-front check when it holds cells (a cached rerun
    writes nothing); the run refuses it once it knows a cell must be written."""
    from slipbench.errors import EnvironmentFault
    from slipbench.store.results import ResultsStore

    store = ResultsStore(tmp_path / "res")
    (tmp_path / "res" / "cells").mkdir(parents=True)
    store.check_writable(unless_stored=True)  # nothing probed: no write, no fault
    (tmp_path / "res").chmod(0o555)
    try:
        if os.geteuid() != 0:
            with pytest.raises(EnvironmentFault, match="found before any work"):
                store.check_writable()
        store.check_writable(unless_stored=True)
    finally:
        (tmp_path / "res").chmod(0o755)
    assert sorted(p.name for p in (tmp_path / "res").iterdir()) == ["cells"]


@pytest.mark.parametrize(
    "argv, message",
    [
        (["evalute"], "No such command 'evalute' (did you mean 'evaluate'?); commands: bench,"),
        (["histroy", "steps"], "No such command 'histroy' (did you mean 'history'?)"),
        (["history", "stpes"], "No such command 'stpes' (did you mean 'steps'?); commands: add,"),
        (["dataset", "valdate"], "No such command 'valdate' (did you mean 'validate'?)"),
        (["zzz"], "No such command 'zzz'; commands: bench, calibrate, compare,"),
        (["evaluate", "--protocl", "window-size"], "Did you mean one of: '--protocol'"),
        (["report", "--formt", "md"], "Did you mean one of: '--format'"),
    ],
)
def test_a_mistyped_command_or_option_suggests_the_closest(argv, message, cli):
    code, _, err = cli(argv)
    assert code == 2 and message in err, err
