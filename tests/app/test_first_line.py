"""A newcomer's first command (the README's LSTM run on a fresh install) says what it is doing
before it does it: its first line announces the default dataset's simulation, and the LSTM's
kernels compile beside it, announced before the child that compiles them starts. Not timed:
``benchmarks/bench_first_line.py`` measures the seconds."""

from __future__ import annotations

import pytest

import slipbench.data.defaults as defaults
from slipbench.detectors import lstm_compile
from slipbench.errors import DataError

README = ["evaluate", "--detector", "lstm", "--protocol", "material-holdout", "--split", "grouped"]


class Stop(DataError):
    """Ends the run where the test has seen what it came for."""


@pytest.fixture
def seen(monkeypatch, capsys, tmp_path):
    """What the run had printed (stdout, stderr) when each step began, in order; a cold cache
    (the dataset's and the kernels'), the compile child and the simulation faked."""
    log: list[tuple[str, str, str]] = []

    def step(name: str) -> None:
        out = capsys.readouterr()
        log.append((name, out.out, out.err))

    class Child:
        def __init__(self):
            step("compile child started")

        def wait(self, say):
            step("compile child waited for")
            raise Stop("the test ends here")

    def simulate(path, scale, seed):
        step("simulation started")
        raise Stop("the test ends here")

    def cached(group):
        step("kernel cache looked at")
        return False

    monkeypatch.setenv("SLIPBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(lstm_compile, "_child", None)
    monkeypatch.setattr(lstm_compile, "_Child", Child)
    monkeypatch.setattr(lstm_compile, "cached", cached)
    monkeypatch.setattr(defaults, "synthesize", simulate)
    return log


def test_a_cold_run_first_says_it_simulates_then_compiles_beside_it(seen, tmp_path, cli):
    code, _, _ = cli([*README, "--out", str(tmp_path / "results")])
    assert code == Stop.exit_code
    looked, started, simulated = seen[0], seen[1], seen[2]
    first = f"simulating the default dataset (first use; scale 0.05, seed 0) into {tmp_path}"
    assert looked[0] == "kernel cache looked at"  # the detector imported, the options checked
    assert looked[1].startswith(first) and looked[1].count("\n") == 1 and looked[2] == ""
    assert started[0] == "compile child started" and started[1] == ""
    assert started[2].startswith("lstm: compiling its numba kernels once for this machine")
    assert simulated[0] == "simulation started" and simulated[1:] == ("", "")


def test_a_cold_kernel_cache_alone_is_the_first_line(seen, tmp_path, cli, small_path):
    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / defaults.default_dataset_path(0.02, 1).name).symlink_to(small_path)  # cached
    code, _, _ = cli([*README, "--scale", "0.02", "--seed", "1", "--out", str(tmp_path / "r")])
    assert code == Stop.exit_code
    names = [name for name, _, _ in seen]
    assert names[:2] == ["kernel cache looked at", "compile child started"]
    assert names[-1] == "compile child waited for" and "simulation started" not in names
    assert seen[0][1:] == ("", "")  # nothing said before it
    assert seen[1][2].startswith("lstm: compiling its numba kernels once for this machine")
