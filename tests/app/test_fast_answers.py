"""Answers that need little work do little: a command imports what it needs when it needs it,
workers start only when a cell must run, and a fully cached run is read from its results folder
without the dataset's samples. What it costs is measured in benchmarks/bench_fixed_costs.py;
here, what each answer may not touch."""

from __future__ import annotations

import json
import subprocess
import sys

import pandas as pd
import pytest

HEAVY = ("numpy", "pandas", "pyarrow", "scipy", "sklearn", "numba", "statsmodels", "torch")

PROBE = """
import json, sys
from slipbench.app.cli import main
code = 0
try:
    main(sys.argv[1:])
except SystemExit as exc:
    code = exc.code
heavy = sorted({m.split(".")[0] for m in sys.modules} & set(HEAVY))
print(json.dumps({"code": code, "heavy": heavy}), file=sys.stderr)
"""


def _probe(argv: list[str], tmp_path) -> dict:
    done = subprocess.run(
        [sys.executable, "-c", PROBE.replace("HEAVY", repr(HEAVY)), *argv],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    return json.loads(done.stderr.strip().splitlines()[-1])


@pytest.mark.parametrize(
    "argv",
    [
        ["--version"],
        ["evaluate", "--detector", "holwge", "--protocol", "window-size"],
        ["evaluate", "--detector", "holweg", "--protocol", "window-sise"],
        ["nonsense"],
        ["evalute"],
    ],
)
def test_the_answers_that_need_no_data_import_no_numerics(argv, tmp_path):
    got = _probe(argv, tmp_path)
    assert got["code"] in (0, 2) and got["heavy"] == [], got


@pytest.fixture
def cached(unit, tmp_path, cli):
    """A results folder holding every cell of a small window-size run, and its printed output."""
    out = tmp_path / "out"
    argv = ["evaluate", "--detector", "holweg", "--protocol", "window-size"]
    argv += ["--protocol-param", "windows=[25,50]", "--dataset", str(unit), "--out", str(out)]
    code, text, err = cli([*argv, "--quiet"])
    assert code == 0, err
    return argv, text


@pytest.mark.slow
def test_a_fully_cached_rerun_reads_no_sample_and_starts_no_worker(cached, cli, monkeypatch):
    import slipbench.data.read
    import slipbench.engine.executors

    def forbidden(*args, **kwargs):
        raise AssertionError("a fully cached run needs neither the samples nor a worker")

    monkeypatch.setattr(slipbench.data.read, "read_dataset", forbidden)
    monkeypatch.setattr(slipbench.engine.executors, "_Pool", forbidden)
    argv, first = cached
    code, again, err = cli([*argv, "--quiet"])
    assert code == 0, err
    assert again == first  # the same tables, the same closing line


@pytest.mark.slow
def test_a_rerun_with_a_cell_to_compute_reads_the_dataset_whole(cached, cli, monkeypatch):
    """New cells (a second seed) send the run the whole way: the samples are read (and checked
    against their fingerprint), the new cells computed, the stored ones reused."""
    import slipbench.data.read

    reads = []
    read = slipbench.data.read.read_dataset
    monkeypatch.setattr(
        slipbench.data.read, "read_dataset", lambda path: reads.append(path) or read(path)
    )
    argv, _ = cached
    out = argv[argv.index("--out") + 1]
    before = pd.read_parquet(f"{out}/results.parquet").set_index("key")["finished_at"]
    code, _, err = cli([*argv, "--repeats", "2", "--quiet"])
    assert code == 0, err
    assert len(reads) == 1
    after = pd.read_parquet(f"{out}/results.parquet").set_index("key")
    assert sorted(after["seed"]) == [0, 0, 1, 1]
    assert after.loc[before.index, "finished_at"].equals(before)  # seed 0 reused, not rerun


def test_the_recordings_and_stored_fingerprint_are_those_the_whole_read_gives(small_path):
    from slipbench.data.read import read_dataset, read_recordings

    whole = read_dataset(small_path)
    recordings, fingerprint = read_recordings(small_path)
    assert fingerprint == whole.fingerprint
    pd.testing.assert_frame_equal(recordings, whole.recordings[list(recordings.columns)])
    assert set(recordings.columns) == set(whole.recordings.columns)


def test_a_dataset_without_a_stored_fingerprint_gives_no_shortcut(small_path, tmp_path):
    """Written by another tool: only a whole read can say what its content is."""
    import pyarrow.parquet as pq

    from slipbench.data.read import read_recordings
    from slipbench.data.schema import FINGERPRINT_KEY, RECORDINGS_FILE, SAMPLES_FILE

    for name in (RECORDINGS_FILE, SAMPLES_FILE):
        table = pq.read_table(small_path / name)
        meta = {k: v for k, v in table.schema.metadata.items() if k != FINGERPRINT_KEY}
        (tmp_path / "copy").mkdir(exist_ok=True)
        pq.write_table(table.replace_schema_metadata(meta), tmp_path / "copy" / name)
    assert read_recordings(tmp_path / "copy") is None
    assert read_recordings(tmp_path / "absent") is None


def test_cached_rows_are_the_runs_rows_or_none(unit, tmp_path):
    from slipbench.data.read import read_dataset, read_recordings
    from slipbench.engine.cached import cached_rows
    from slipbench.engine.runner import Run, evaluate
    from slipbench.protocols.window_size import WindowSize
    from slipbench.store.results import ResultsStore

    store = ResultsStore(tmp_path / "out")
    run = Run("holweg", WindowSize(windows=[50]), "grouped", 0)
    known = read_recordings(unit)
    assert cached_rows(*known, [run], store) is None  # nothing stored yet
    rows = evaluate(read_dataset(unit), [run], store, jobs=0, progress=False)
    pd.testing.assert_frame_equal(cached_rows(*known, [run], store), rows)
    seed1 = Run("holweg", WindowSize(windows=[50]), "grouped", 1)
    assert cached_rows(*known, [run, seed1], store) is None  # seed 1 must be computed


def test_no_task_starts_no_worker(monkeypatch):
    import slipbench.engine.executors as executors

    monkeypatch.setattr(executors, "_Pool", lambda *a: pytest.fail("a pool was started"))
    assert (
        list(executors.process_pool([], lambda task: task, executors.Executor(2, None, None), None))
        == []
    )
