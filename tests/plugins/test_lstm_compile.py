"""The LSTM's kernels compiled once per machine (lstm_compile) and its lockstep progress."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

from slipbench.base import FitJob, listening
from slipbench.detectors import lstm_compile
from slipbench.detectors.lstm import LSTM
from slipbench.engine import runner


@pytest.fixture
def fake_group(monkeypatch, tmp_path):
    """A kernel group whose "compile" records each call, in a cache folder of its own."""
    calls: list[str] = []
    monkeypatch.setattr(lstm_compile, "cache_folder", lambda: tmp_path)
    monkeypatch.setattr(lstm_compile, "_ready", set())
    monkeypatch.setitem(lstm_compile._EXERCISE, "fake", lambda: calls.append("fake"))
    return calls


def test_a_group_compiles_once_per_process_and_is_stamped(fake_group, monkeypatch):
    assert not lstm_compile.cached("fake")
    lstm_compile.ready("fake")
    lstm_compile.ready("fake")
    assert fake_group == ["fake"] and lstm_compile.cached("fake")


def test_a_group_called_back_under_the_lock_does_not_wait_for_itself(fake_group, monkeypatch):
    # an exercise fits a detector, whose own calls come back to ready(): flock is not reentrant
    monkeypatch.setitem(lstm_compile._EXERCISE, "outer", lambda: lstm_compile.ready("fake"))
    lstm_compile.ready("outer")
    assert fake_group == ["fake"] and lstm_compile.cached("outer")


def test_a_second_process_waits_for_the_compile_in_flight(fake_group, tmp_path):
    # another process holds the cache folder's lock (compiling) and writes a file as it lets go
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            textwrap.dedent(f"""
            import pathlib, sys, time
            from slipbench.atomic import folder_lock
            with folder_lock({str(tmp_path)!r}):
                print("held", flush=True)
                time.sleep(1.0)
                pathlib.Path({str(tmp_path / "released")!r}).write_text("")
            """),
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
    lstm_compile._EXERCISE["fake"] = lambda: fake_group.append(
        "after" if (tmp_path / "released").exists() else "during"
    )
    lstm_compile.ready("fake")
    assert holder.wait() == 0 and fake_group == ["after"]


def test_a_failed_exercise_leaves_the_group_unready_and_unstamped(fake_group, monkeypatch):
    def broken():
        raise RuntimeError("LLVM ran out of memory")

    monkeypatch.setitem(lstm_compile._EXERCISE, "fake", broken)
    with pytest.raises(RuntimeError):
        lstm_compile.ready("fake")
    assert "fake" not in lstm_compile._ready and not lstm_compile.cached("fake")


class FakeChild:
    """A compile child (subprocess.Popen) that is done when ``done`` says so, exits with
    ``code`` and writes ``err`` to its stderr file."""

    started: list[list[str]] = []

    def __init__(self, argv, code=0, err="", **kw):
        FakeChild.started.append(argv)
        self.code, self.killed, self.done = code, False, True
        kw["stderr"].write(err)

    def poll(self):
        return self.code if self.done else None

    def wait(self):
        return self.code

    def kill(self):
        self.killed = True


@pytest.fixture
def children(monkeypatch):
    """Compile children faked (FakeChild), none started yet; the kernels not cached until
    a child was waited for."""
    state = {"cached": False}
    monkeypatch.setattr(FakeChild, "started", [])
    monkeypatch.setattr(lstm_compile, "_child", None)
    monkeypatch.setattr(lstm_compile, "cached", lambda group: state["cached"])
    monkeypatch.setattr(lstm_compile.subprocess, "Popen", FakeChild)
    waited = lstm_compile._Child.wait

    def wait(self, say):
        waited(self, say)
        state["cached"] = True

    monkeypatch.setattr(lstm_compile._Child, "wait", wait)
    return FakeChild.started


def test_compiling_ahead_says_so_first_and_then_how_long(children):
    said: list[str] = []
    lstm_compile.compile_ahead(said.append)
    assert said[0].startswith("lstm: compiling its numba kernels once for this machine, about ")
    assert said[1].startswith("lstm: kernels compiled in ") and len(children) == 1
    assert "lstm_compile.ready('predict', 'lockstep')" in children[0][-1]
    lstm_compile.compile_ahead(said.append)  # cached now: nothing said, nothing run
    assert len(said) == 2 and len(children) == 1


def test_a_compile_started_ahead_is_waited_for_once_or_killed_at_exit(children, monkeypatch):
    said: list[str] = []
    lstm_compile.start_ahead(said.append)
    lstm_compile.start_ahead(said.append)  # one child, however often the engine starts it
    assert len(children) == 1 and len(said) == 1 and lstm_compile._child is not None
    lstm_compile.compile_ahead(said.append)  # waits for that child: no second one
    assert len(children) == 1 and said[1].startswith("lstm: kernels compiled in ")
    monkeypatch.setattr(lstm_compile, "cached", lambda group: False)
    lstm_compile.start_ahead(said.append)
    child = lstm_compile._child
    assert child is not None
    child.process.done = False  # still compiling when the run ends without waiting for it
    child.stop()  # what atexit calls
    assert child.process.killed


def test_a_failed_compile_ahead_names_its_exit_and_last_line(children, monkeypatch):
    from slipbench.errors import EnvironmentFault

    monkeypatch.setattr(
        lstm_compile.subprocess,
        "Popen",
        lambda argv, **kw: FakeChild(argv, 1, "x\nMemoryError: LLVM\n", **kw),
    )
    with pytest.raises(EnvironmentFault, match=r"exit 1\): MemoryError: LLVM"):
        lstm_compile.compile_ahead(lambda _: None)


def test_the_runner_prepares_each_class_once_before_its_workers(monkeypatch):
    prepared: list[type] = []

    class Toy(LSTM):
        @classmethod
        def prepare(cls, say):
            prepared.append(cls)
            say("toy: preparing")

    class Cell:
        def __init__(self, detector):
            self.run = type("R", (), {"detector": detector})()

    tasks = [type("T", (), {"cells": [Cell(Toy())]})() for _ in range(3)]
    runner._prepare(tasks, say_it=False)  # type: ignore[arg-type]
    assert prepared == [Toy]


def test_lockstep_reports_its_models_and_epochs_to_the_bar():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(60, 10)).astype(np.float32)
    y = (np.arange(60) % 2).astype(np.int8)
    reports: list[dict] = []
    dets = [LSTM(max_epochs=(2, 1), learning_rates=(0.01, 0.001), device="cpu") for _ in range(3)]
    with listening(reports.append):
        LSTM.fit_lockstep(dets, [FitJob(x, y, seed) for seed in range(3)])
    assert reports[0] == {"detector": "lstm", "step": 0, "total": 3, "unit": "epoch", "models": 3.0}
    steps = [r["step"] for r in reports]
    assert steps == list(range(len(reports))) and steps[-1] == max(len(d.history_) for d in dets)
    last = reports[-1]
    assert set(last) == {"detector", "step", "total", "unit", "models", "loss"}
    assert runner.progress_line(reports[1]).startswith("lstm: epoch 1/3, models ")
