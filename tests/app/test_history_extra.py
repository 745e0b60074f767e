"""plotly is the ``history`` extra's: the plain install (``pip install .``) brings neither it
nor ruptures (the oracle of the steps' segmentation, a test's), the test extra brings both, and
``slipbench history page`` without plotly is refused before any work in one line naming the
install command (exit 2); ``add`` and ``steps`` need nothing beyond the plain install. The missing library is
simulated (``sys.modules[name] = None`` makes its import fail), never uninstalled."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
import tomllib

from slipbench.app.commands.history import EXTRA, INSTALL

ROOT = next(p for p in Path(__file__).resolve().parents if (p / "pyproject.toml").is_file())
COMMANDS = (["add", "results", "--commit", "c0"], ["steps"])


def _requirements(spec: list[str]) -> set[str]:
    return {r.split(">")[0].split("=")[0].split("[")[0].strip().lower() for r in spec}


def test_the_plain_install_brings_no_history_library():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extras = project["optional-dependencies"]
    assert not _requirements(project["dependencies"]) & {*EXTRA, "ruptures"}
    assert _requirements(extras["history"]) == set(EXTRA)
    assert {*EXTRA, "ruptures"} <= _requirements(extras["test"])  # the tests run the site's code


def _without(monkeypatch, names) -> None:
    for name in names:
        monkeypatch.setitem(sys.modules, name, None)


def test_the_page_without_its_extra_names_it(tmp_path, monkeypatch, cli):
    _without(monkeypatch, EXTRA)
    site = tmp_path / "site"
    code, out, err = cli(["history", "page", "--history", str(tmp_path / "h"), "--out", str(site)])
    assert code == 2, err
    assert err.count("\n") == 1 and INSTALL in err, err
    assert all(name in err for name in EXTRA) and out == ""
    assert not site.exists()  # refused before any work


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: c[0])
def test_add_and_steps_need_no_extra(tmp_path, monkeypatch, cli, command):
    """Without plotly or ruptures, add and steps go on to their own errors (here: nothing to
    read), never the extra's line."""
    _without(monkeypatch, (*EXTRA, "ruptures"))
    code, _, err = cli(["history", *command, "--history", str(tmp_path / "nothing")])
    assert code == 2 and INSTALL not in err, err
