"""ruptures and plotly are the ``history`` extra's: the plain install (``pip install .``) brings
neither, the test extra brings both, and every ``slipbench history`` command without them is
refused before any work in one line naming the install command (exit 2). The missing library is
simulated (``sys.modules[name] = None`` makes its import fail), never uninstalled."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
import tomllib

from slipbench.app.commands.history import EXTRA, INSTALL

ROOT = next(p for p in Path(__file__).resolve().parents if (p / "pyproject.toml").is_file())
COMMANDS = (["add", "results", "--commit", "c0"], ["steps"], ["page"])


def _requirements(spec: list[str]) -> set[str]:
    return {r.split(">")[0].split("=")[0].split("[")[0].strip().lower() for r in spec}


def test_the_plain_install_brings_no_history_library():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extras = project["optional-dependencies"]
    assert not _requirements(project["dependencies"]) & set(EXTRA)
    assert _requirements(extras["history"]) == set(EXTRA)
    assert set(EXTRA) <= _requirements(extras["test"])  # the tests run the history's code


@pytest.mark.parametrize("missing", [EXTRA, EXTRA[:1], EXTRA[1:]])
@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: c[0])
def test_history_without_its_extra_names_it(tmp_path, monkeypatch, cli, command, missing):
    for name in missing:
        monkeypatch.setitem(sys.modules, name, None)
    history = tmp_path / "history"
    code, out, err = cli(["history", *command, "--history", str(history)])
    assert code == 2, err
    assert err.count("\n") == 1 and INSTALL in err, err
    assert all(name in err for name in missing) and out == ""
    assert not history.exists()  # refused before any work


def test_with_its_extra_the_command_runs_on(tmp_path, cli):
    """The check passes where both import (here): the command goes on to its own errors."""
    code, _, err = cli(["history", "steps", "--history", str(tmp_path / "nothing")])
    assert code == 2 and INSTALL not in err and "no history" in err, err
