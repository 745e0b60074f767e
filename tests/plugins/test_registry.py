"""Plugins from a folder and from an installed distribution's entry point."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import toys

from slipbench.base import BaseDetector
from slipbench.engine.registry import Registry, add_plugin_folder, detectors
from slipbench.errors import PluginError, UsageError

PLUGIN = toys.source(toys.Energy)


def test_builtins_are_listed_without_importing_them():
    assert "holweg" in detectors.names()


def test_plugin_folder_and_broken_plugin(tmp_path):
    (tmp_path / "my_energy.py").write_text(PLUGIN)
    (tmp_path / "broken.py").write_text("raise RuntimeError('boom')\n")
    reg = Registry("detector", BaseDetector, "slipbench.detectors")
    reg.add_folder(tmp_path)
    assert {"my-energy", "broken", "holweg"} <= set(reg.names())
    assert reg.get("my-energy").__name__ == "Energy"
    with pytest.raises(
        PluginError,
        match=r"detector 'broken' \(plugin file .*broken.py\) failed to import: RuntimeError: boom",
    ):
        reg.get("broken")
    with pytest.raises(
        UsageError, match="unknown detector 'x'; available: .*broken, .*holweg, .*my-energy"
    ):
        reg.get("x")


def test_tests_and_helpers_beside_plugins_are_not_plugins(tmp_path):
    """pytest's files (test_*.py, *_test.py, conftest.py) and helpers (_name.py) sit beside the
    plugins they serve without being loaded as broken plugins."""
    (tmp_path / "energy.py").write_text(PLUGIN)
    for name in ("test_energy.py", "energy_test.py", "conftest.py", "_tools.py"):
        (tmp_path / name).write_text("raise RuntimeError('not a plugin')\n")
    reg = Registry("detector", BaseDetector, "slipbench.detectors")
    reg.add_folder(tmp_path)
    mine = [n for n in reg.names() if reg.provenance(n).startswith("plugin file")]
    assert mine == ["energy"]


@pytest.mark.slow
def test_the_example_plugins_tests_pass_beside_it(tmp_path):
    """The plugins guide's layout: `pytest plugins/` runs the conformance suite on the plugin."""
    folder = Path(__file__).resolve().parents[2] / "examples" / "plugin-repo" / "plugins"
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(folder)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert " passed" in done.stdout and "failed" not in done.stdout


def test_duplicate_names_name_both_origins(tmp_path):
    (tmp_path / "holweg.py").write_text(PLUGIN)
    reg = Registry("detector", BaseDetector, "slipbench.detectors")
    with pytest.raises(
        UsageError,
        match=r"two detectors are named 'holweg': one from entry point slipbench.detectors.holweg:Holweg \(slipbench\), one from plugin file",
    ):
        reg.add_folder(tmp_path)


def test_missing_plugin_folder():
    with pytest.raises(UsageError, match="does not exist"):
        add_plugin_folder("/nonexistent/plugins")


@pytest.mark.slow
def test_entry_point_plugin_from_an_installed_distribution(tmp_path):
    """Build and install a real distribution exposing `slipbench.detectors` into a target folder."""
    src = tmp_path / "src"
    (src / "thirdparty_slip").mkdir(parents=True)
    (src / "thirdparty_slip" / "__init__.py").write_text(PLUGIN)
    (src / "pyproject.toml").write_text(
        textwrap.dedent("""
        [build-system]
        requires = ["setuptools>=68"]
        build-backend = "setuptools.build_meta"
        [project]
        name = "thirdparty-slip"
        version = "0.1"
        [project.entry-points."slipbench.detectors"]
        third-energy = "thirdparty_slip:Energy"
    """)
    )
    target = tmp_path / "site"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "--target",
            str(target),
            str(src),
        ],
        check=True,
    )
    code = textwrap.dedent("""
        import numpy as np
        from slipbench.engine.registry import detectors
        cls = detectors.get("third-energy")
        x = np.r_[np.zeros((4, 8)), np.ones((4, 8))]
        print(cls.__name__, cls().fit(x, [0]*4 + [1]*4).predict(x).tolist())
    """)
    env = {"PYTHONPATH": str(target), "PATH": ""}
    # run outside the source tree, so that `slipbench` is the installed package
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=tmp_path
    )
    assert done.returncode == 0, done.stderr
    out = done.stdout
    assert out.strip() == "Energy [0, 0, 0, 0, 1, 1, 1, 1]"


def test_a_folder_plugin_runs_the_public_conformance_suite(tmp_path):
    from slipbench.testing import check_detector

    (tmp_path / "my_energy.py").write_text(PLUGIN)
    reg = Registry("detector", BaseDetector, "slipbench.detectors")
    reg.add_folder(tmp_path)
    check_detector(reg.get("my-energy")())
