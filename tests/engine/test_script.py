"""The Python API from a script file, as a user writes one: without an `if __name__ ==
"__main__":` guard the default (jobs=1) runs in this process and succeeds, where before each
worker imported the script again and the run died with "All workers expired"; asking such a
script for more workers is refused with one line that says what to add. The scripts set the
spawn start method, as on macOS and Windows."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

SCRIPT = """\
import multiprocessing
from slipbench.data.read import read_dataset
from slipbench.engine.runner import Run, evaluate
from slipbench.store.results import ResultsStore
{body}
"""
CALL = """\
multiprocessing.set_start_method("spawn")
rows = evaluate(read_dataset({data!r}), Run("holweg", "window-size"), ResultsStore({out!r}),
                progress=False{extra})
print("cells", len(rows), sorted(set(rows["status"])))
"""


def run_script(tmp_path, body: str) -> subprocess.CompletedProcess:
    path = tmp_path / "my_script.py"
    path.write_text(SCRIPT.format(body=body))
    return subprocess.run(
        [sys.executable, str(path)], capture_output=True, text=True, cwd=tmp_path, timeout=300
    )


@pytest.mark.slow
def test_a_script_without_a_guard_runs_in_this_process(unit, tmp_path):
    done = run_script(tmp_path, CALL.format(data=str(unit), out=str(tmp_path / "o"), extra=""))
    assert done.returncode == 0, done.stderr
    assert "cells 6 ['ok']" in done.stdout
    assert "Traceback" not in done.stderr and "workers expired" not in done.stderr


@pytest.mark.slow
def test_a_script_without_a_guard_asking_for_workers_is_refused_in_one_line(unit, tmp_path):
    call = CALL.format(data=str(unit), out=str(tmp_path / "o"), extra=", jobs=2")
    done = run_script(tmp_path, call)
    assert done.returncode == 1
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("slipbench.errors.UsageError: ") and "my_script.py:6: jobs=2" in last
    assert 'put its calls under `if __name__ == "__main__":`' in last
    assert "workers expired" not in done.stderr and "bug in slipbench" not in done.stderr
    assert not (tmp_path / "o").exists()  # refused before any work


@pytest.mark.slow
def test_a_guarded_script_still_gets_workers_and_time_limits(unit, tmp_path):
    call = CALL.format(data=str(unit), out=str(tmp_path / "o"), extra=", jobs=2, cell_timeout=300")
    done = run_script(tmp_path, 'if __name__ == "__main__":\n' + textwrap.indent(call, "    "))
    assert done.returncode == 0, done.stderr
    assert "cells 6 ['ok']" in done.stdout
