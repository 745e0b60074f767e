"""From the repository root the source tree's slipbench/ comes first on sys.path (`python -m
...`): it holds the built-in plugins itself, so the command and the tests behave there as
they do on the installed package."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_python_m_slipbench_from_the_root_loads_every_builtin():
    done = subprocess.run(
        [sys.executable, "-m", "slipbench", "list", "--json"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert done.returncode == 0, done.stderr
    listed = json.loads(done.stdout)
    states = {e["name"]: e["status"] for kind in listed.values() for e in kind}
    assert states["holweg"] == states["lstm"] == states["window-size"] == "ok", states
    assert not [n for n, s in states.items() if s in ("import error", "missing dependency")]


@pytest.mark.slow
def test_python_m_pytest_from_the_root_tests_the_source_trees_plugins():
    code = "import slipbench.detectors.holweg as m, slipbench.protocols as p; print(m.__file__)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    assert Path(done.stdout.strip()) == ROOT / "slipbench" / "detectors" / "holweg.py"
