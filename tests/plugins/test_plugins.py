"""Third-party plugins through the public contract alone: an installed package holding a detector
and a protocol with its own layout runs `evaluate`, `report` and `compare`; folder plugins reach
`report` with --plugins; `list` shows parameters and status; the contract's holes are closed."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pandas as pd
import pytest
import toys

import slipbench
from slipbench.base import BaseDetector
from slipbench.engine.registry import Registry, detectors
from slipbench.errors import PluginError

DETECTOR = toys.source(toys.Energy)
PROTOCOL = toys.source(toys.TwoWindows)


def _slipbench(args: list[str], env: dict, cwd) -> subprocess.CompletedProcess:
    code = "import sys; from slipbench.app.cli import main; main(sys.argv[1:])"
    return subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, env=env, cwd=cwd
    )


@pytest.mark.slow
def test_an_installed_plugin_package_runs_evaluate_report_and_compare(tmp_path, small_path):
    src = tmp_path / "src"
    (src / "labslip").mkdir(parents=True)
    (src / "labslip" / "__init__.py").write_text("")
    (src / "labslip" / "energy.py").write_text(DETECTOR)
    (src / "labslip" / "two_windows.py").write_text(PROTOCOL)
    (src / "pyproject.toml").write_text(
        textwrap.dedent("""
        [build-system]
        requires = ["setuptools>=68"]
        build-backend = "setuptools.build_meta"
        [project]
        name = "labslip"
        version = "0.1"
        dependencies = ["slipbench"]
        [project.entry-points."slipbench.detectors"]
        energy = "labslip.energy:Energy"
        [project.entry-points."slipbench.protocols"]
        two-windows = "labslip.two_windows:TwoWindows"
    """)
    )
    site = tmp_path / "site"
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
            str(site),
            str(src),
        ],
        check=True,
    )
    env = {"PYTHONPATH": str(site), "PATH": "", "SLIPBENCH_CACHE": str(tmp_path / "cache")}
    common = [
        "evaluate",
        "--detector",
        "energy",
        "--protocol",
        "two-windows",
        "--dataset",
        str(small_path),
        "--quiet",
    ]
    for out, quantile in (("base", "0.5"), ("candidate", "0.9")):
        done = _slipbench(
            [*common, "--out", str(tmp_path / out), "--param", f"quantile={quantile}"],
            env,
            tmp_path,
        )
        assert done.returncode == 0, done.stderr
        assert (
            "Energy at two window lengths." in done.stdout
        )  # evaluate prints the protocol's own table
    done = _slipbench(
        ["report", str(tmp_path / "base"), "--plots", str(tmp_path / "fig")], env, tmp_path
    )
    assert done.returncode == 0, done.stderr
    assert "**Energy at two window lengths.** Classification Accuracy (%) at Window." in done.stdout
    assert "| Sensor | Finger |" in done.stdout.replace("  ", " ").replace("  ", " ")
    assert (tmp_path / "fig" / "two-windows-energy.png").stat().st_size > 1000
    done = _slipbench(
        ["compare", str(tmp_path / "base"), str(tmp_path / "candidate")], env, tmp_path
    )
    assert done.returncode in (0, 1, 6), done.stderr  # a verdict: none, regressed, undecided
    assert "two-windows" in done.stdout and "energy" in done.stdout
    done = _slipbench(["list", "--json"], env, tmp_path)
    listed = {e["name"]: e for e in json.loads(done.stdout)["detectors"]}
    assert listed["energy"]["parameters"] == {
        "quantile": {"default": 0.5, "constraint": "a float in [0.0, 1.0]"}
    }
    assert listed["energy"]["status"] == "ok" and listed["energy"]["description"].startswith(
        "Mean absolute signal"
    )


@pytest.mark.slow
def test_report_reads_a_folder_protocols_layout_with_plugins(tmp_path, small_path, cli):
    plugins = tmp_path / "plugins"
    (plugins / "protocols").mkdir(parents=True)
    (plugins / "detectors").mkdir()
    (plugins / "protocols" / "two_windows.py").write_text(PROTOCOL)
    (plugins / "detectors" / "energy.py").write_text(DETECTOR)
    out = tmp_path / "out"
    code, _, err = cli(
        [
            "evaluate",
            "--detector",
            "energy",
            "--protocol",
            "two-windows",
            "--dataset",
            str(small_path),
            "--plugins",
            str(plugins),
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert code == 0, err
    # a new process knows no plugin folder: the rows recorded the protocol's layout and
    # presentation, so its report is the one the plugin's own would give
    done = _slipbench(["report", str(out)], {"PATH": ""}, tmp_path)
    code, text, _ = cli(["report", str(out), "--plugins", str(plugins)])
    assert done.returncode == 0 and code == 0
    assert "**Energy at two window lengths.**" in done.stdout
    assert "Laid out from its cell keys" not in done.stdout + text
    assert done.stdout == text


def test_list_shows_parameters_and_status(tmp_path, cli):
    (tmp_path / "broken.py").write_text("raise RuntimeError('boom')\n")
    (tmp_path / "needs_dep.py").write_text(toys.source(toys.NeedsDep))
    (tmp_path / "missing_import.py").write_text("import no_such_module_slipbench\n")
    code, text, _ = cli(["list", "--plugins", str(tmp_path)])
    assert code == 0
    assert "holweg" in text and "band=None" in text and "keep=0.8  (a float in [0.0, 1.0])" in text
    # where each comes from: the installing package and its version, or the plugin file
    assert f"from built in (slipbench {slipbench.__version__})" in text
    assert f"from plugin file {tmp_path / 'needs_dep.py'}" in text
    code, text, _ = cli(["list", "--plugins", str(tmp_path), "--json"])
    found = {e["name"]: e for e in json.loads(text)["detectors"]}
    assert found["broken"]["status"] == "import error" and "boom" in found["broken"]["detail"]
    assert (
        found["needs-dep"]["status"] == "unavailable"
        and "needs no_such_module_slipbench" in found["needs-dep"]["detail"]
    )
    assert found["missing-import"]["status"] == "missing dependency"
    assert (
        found["lstm"]["status"] == "ok"
        and found["lstm"]["parameters"]["max_epochs"]["default"] == [20, 5, 3, 2]
        or found["lstm"]["parameters"]["max_epochs"]["default"] == (20, 5, 3, 2)
    )


def test_plugin_files_with_one_stem_in_two_folders_stay_apart(tmp_path):
    for folder, quantile in (("a", "0.25"), ("b", "0.75")):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "energy.py").write_text(
            DETECTOR.replace("quantile=0.5", f"quantile={quantile}")
        )
    one, two = (Registry("detector", BaseDetector, "slipbench.detectors") for _ in range(2))
    one.add_folder(tmp_path / "a")
    two.add_folder(tmp_path / "b")
    a, b = one.get("energy"), two.get("energy")
    assert a is not b and a.__module__ != b.__module__
    assert a().quantile == 0.25 and b().quantile == 0.75


def test_the_registered_name_is_the_one_id(tmp_path):
    (tmp_path / "energy.py").write_text(
        DETECTOR.replace(
            "    _parameter_constraints", '    name = "other"\n    _parameter_constraints'
        )
    )
    reg = Registry("detector", BaseDetector, "slipbench.detectors")
    reg.add_folder(tmp_path)
    with pytest.raises(
        PluginError, match="declares name = 'other'; its id is the name it is registered under"
    ):
        reg.get("energy")


def test_ids_of_builtins_subclasses_and_saved_models(tmp_path):
    from slipbench.detectors.holweg import Holweg

    assert detectors.id_of(Holweg) == "holweg"

    class MyHolweg(Holweg):
        pass

    assert detectors.id_of(MyHolweg) == "my-holweg"  # a subclass has its own id, not its parent's
    (tmp_path / "energy.py").write_text(DETECTOR)
    reg = Registry("detector", BaseDetector, "slipbench.detectors")
    reg.add_folder(tmp_path)
    cls = reg.get("energy")
    x = pd.DataFrame({"a": [0.0] * 8}).to_numpy().repeat(8, axis=1)
    x[4:] = 1.0
    fitted = cls().fit(x, [0] * 4 + [1] * 4)
    fitted.save(tmp_path / "model.npz")
    loaded = BaseDetector.load(
        tmp_path / "model.npz"
    )  # the class is found by module, not by a name attribute
    assert type(loaded) is cls and loaded.predict(x).tolist() == [0] * 4 + [1] * 4
