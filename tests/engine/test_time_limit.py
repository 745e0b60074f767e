"""A default time limit per model: a plugin whose fit never returns ends at it with a line
naming its cells, the limit is said where the run starts and in `run --plan`, 0 means none;
every process a plugin started ends with its worker, even one in a session of its own."""

from __future__ import annotations

from pathlib import Path

import psutil
import pytest
import toys

from slipbench.data.read import read_dataset
from slipbench.engine import limits
from slipbench.engine.limits import DEFAULT_CELL_TIMEOUT, cell_limit, limit_words
from slipbench.engine.runner import Run, evaluate
from slipbench.protocols.window_size import WindowSize
from slipbench.store.results import ResultsStore


def test_the_default_applies_to_local_workers_only():
    assert cell_limit(None, 1, None) == DEFAULT_CELL_TIMEOUT == 7200.0
    assert cell_limit(30, 2, None) == 30.0
    assert cell_limit(0, 2, None) is None  # 0: none
    assert cell_limit(None, 0, None) is None  # in this process: nothing could stop it
    assert cell_limit(None, 2, "slurm") is None  # an array has its own time limit
    assert limit_words(None, 2, None) == (
        "time limit: 7200 s per model (the default); "
        "--cell-timeout SECONDS or [run] cell_timeout; 0 for none"
    )
    assert limit_words(0, 2, None).startswith("time limit: none per model (0 given;")
    assert limit_words(None, 0, None).startswith(
        "time limit: none per model (cells run in this process (--jobs 0);"
    )


def _plugin(tmp_path: Path, toy: type) -> Path:
    folder = tmp_path / "plugins"
    folder.mkdir(exist_ok=True)
    (folder / f"{toy.name}.py").write_text(toys.source(toy))
    return folder


def test_a_fit_that_never_returns_ends_at_the_default_limit(cli, unit, tmp_path, monkeypatch):
    monkeypatch.setattr(limits, "DEFAULT_CELL_TIMEOUT", 1.0)  # the default, made small
    code, out, err = cli(
        [
            "evaluate",
            "--plugins",
            str(_plugin(tmp_path, toys.Forever)),
            "--detector",
            "forever",
            "--protocol",
            "window-size",
            "--protocol-param",
            "windows=[50]",
            "--dataset",
            str(unit),
            "--out",
            str(tmp_path / "out"),
        ]
    )
    assert code == 4, err
    assert "time limit: 1 s per model (the default)" in err
    assert "1 cells: 0 ok, 0 skipped, 0 failed, 1 timeout" in out
    assert "window-size/forever" in err and "did not fit and test within 1 s" in err


def _ended(pid_file: Path) -> list[bool]:
    pids = [int(line) for line in pid_file.read_text().split()]
    assert pids, "the plugin started no process"
    out = []
    for pid in pids:
        try:
            proc = psutil.Process(pid)
            out.append(proc.status() == psutil.STATUS_ZOMBIE)  # ended, not reaped yet
        except psutil.NoSuchProcess:
            out.append(True)
    return out


@pytest.mark.parametrize("hang", [False, True], ids=["returns", "hangs"])
def test_processes_a_plugin_started_end_with_its_worker(unit, tmp_path, hang):
    """A child in a session of its own outlived the run where its fit returned; where the fit
    hangs, the time limit stops the worker and the child together."""
    from slipbench.engine import registry

    registry.add_plugin_folder(_plugin(tmp_path, toys.Spawner))
    spawner = registry.detectors.get("spawner")
    pid_file = tmp_path / "pids"
    pid_file.write_text("")
    rows = evaluate(
        read_dataset(unit),
        Run(spawner(pid_file=str(pid_file), hang=hang), WindowSize(windows=[50, 100])),
        ResultsStore(tmp_path / "out"),
        jobs=1,
        cell_timeout=2.0 if hang else None,
        progress=False,
    )
    assert rows["status"].tolist() == ["timeout" if hang else "ok"] * 2, rows["reason"].tolist()
    assert all(_ended(pid_file))


def test_the_plan_states_the_limit(tmp_path):
    from slipbench.app.benchspec import load_benchmark
    from slipbench.app.planning import planning, render

    text = """
[benchmark]
out = "res"
[dataset]
scale = 0.002
[run]
jobs = 2
{limit}
[detectors.holweg]
[protocols.window-size]
windows = [50]
"""
    for limit, said in [
        ("", "Time limit: 7200 s per model (the default);"),
        ("cell_timeout = 0", "Time limit: none per model (0 given;"),
        ("cell_timeout = 90", "Time limit: 90 s per model;"),
    ]:
        path = tmp_path / "bench.toml"
        path.write_text(text.format(limit=limit))
        assert said in render(planning(load_benchmark(path), [], print))
