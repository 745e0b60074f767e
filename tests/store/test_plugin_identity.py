"""The code identity of a folder plugin covers everything it runs: the helper modules and
packages beside it that it imports, and the data files it declares. A change to any of them
changes the cell key (the cell is computed anew); unchanged code keeps its key."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
import toys

from slipbench.base import BaseDetector
from slipbench.engine import plan, registry
from slipbench.engine.plan import Run
from slipbench.errors import PluginError
from slipbench.protocol import Cell, Part
from slipbench.store import keys

UNIT = (("OptoForce20", "index"),)
CELL = Cell({"window": 25}, Part(UNIT, "train"), Part(UNIT, "test"), 25)
# module names of the helpers below: distinct from every other test's, since a module name is
# global to a process
LOCAL = ("idhelper", "idhelper_deep", "idsub")
ENERGY = toys.source(toys.Energy)


@pytest.fixture(autouse=True)
def _forget_imports(monkeypatch):
    """Each load below is a new process's: the plugin folders leave sys.path and the helpers
    sys.modules after the test."""
    monkeypatch.setattr(sys, "path", list(sys.path))
    yield
    _forget()


def _forget() -> None:
    for name in [
        m for m in sys.modules if m.startswith("slipbench_plugin_") or m.split(".")[0] in LOCAL
    ]:
        del sys.modules[name]
    keys._unit_identity.cache_clear()
    keys._with_data.cache_clear()


def cell_key(folder: Path, name: str = "energy") -> str:
    """The key of one cell of the plugin ``name`` of ``folder``, as a fresh process plans it."""
    _forget()
    reg = registry.Registry("detector", BaseDetector, "slipbench.no-such-group")
    reg.add_folder(folder)
    run = Run(reg.get(name)(), "window-size")
    key, model = plan.keys(run, CELL, "fingerprint")
    assert key != model
    return key


def plugin(folder: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_text(text)
    return folder


def test_a_changed_helper_module_changes_the_key(tmp_path):
    folder = plugin(
        tmp_path,
        {
            "energy.py": ENERGY + "\nfrom idhelper import SCALE  # noqa: F401\n",
            "idhelper.py": "import numpy as np\nfrom idhelper_deep import OFFSET\nSCALE = 2.0\n",
            "idhelper_deep.py": "OFFSET = 0\n",  # imported by the helper: followed too
            "unrelated.py": "X = 1\n",  # another plugin of the folder, not imported
        },
    )
    first = cell_key(folder)
    assert cell_key(folder) == first  # unchanged code keeps its key
    labels = [label for label, _ in keys.local_files(folder / "energy.py")]
    assert labels == ["energy.py", "idhelper.py", "idhelper_deep.py"]  # not numpy, not the rest

    (folder / "idhelper.py").write_text(
        "import numpy as np\nfrom idhelper_deep import OFFSET\nSCALE = 3.0\n"
    )
    changed = cell_key(folder)
    assert changed != first
    (folder / "idhelper_deep.py").write_text("OFFSET = 1\n")
    assert cell_key(folder) not in (first, changed)
    (folder / "unrelated.py").write_text("X = 2\n")  # a sibling it does not import
    (folder / "idhelper_deep.py").write_text("OFFSET = 0\n")
    (folder / "idhelper.py").write_text(
        "import numpy as np\nfrom idhelper_deep import OFFSET\nSCALE = 2.0\n"
    )
    assert cell_key(folder) == first  # content-addressed: the old code has its old key


def test_a_changed_subpackage_changes_the_key(tmp_path):
    folder = plugin(
        tmp_path,
        {
            "energy.py": ENERGY + "\n\ndef _scale():\n    from idsub.deep import F\n    return F\n",
            "idsub/__init__.py": "",
            "idsub/deep.py": "F = 1\n",
            "idsub/inner/other.py": "G = 1\n",  # every code file of the package counts
            "idsub/notes.txt": "not code\n",
        },
    )
    first = cell_key(folder)
    assert cell_key(folder) == first
    assert {label for label, _ in keys.local_files(folder / "energy.py")} == {
        "energy.py",
        "idsub/__init__.py",
        "idsub/deep.py",
        "idsub/inner/other.py",
    }
    (folder / "idsub" / "deep.py").write_text("F = 2\n")
    second = cell_key(folder)
    assert second != first
    (folder / "idsub" / "inner" / "other.py").write_text("G = 2\n")
    assert cell_key(folder) not in (first, second)
    (folder / "idsub" / "notes.txt").write_text("edited\n")  # not code, not declared
    assert cell_key(folder) not in (first, second)


DATA_PLUGIN = ENERGY.replace(
    '    """Mean absolute signal above a training quantile."""\n',
    '    """Mean absolute signal above a training quantile."""\n\n'
    '    data_files = ("weights.json", "tables")\n',
)


def test_a_changed_data_file_changes_the_key(tmp_path):
    assert "data_files" in DATA_PLUGIN
    folder = plugin(
        tmp_path,
        {
            "energy.py": DATA_PLUGIN,
            "weights.json": '{"w": [0.5]}\n',
            "tables/a.csv": "x\n1\n",
        },
    )
    first = cell_key(folder)
    assert cell_key(folder) == first
    cls = sys.modules[
        next(m for m in sys.modules if m.startswith("slipbench_plugin_energy"))
    ].Energy
    assert [label for label, _ in keys.data_files(cls)] == ["weights.json", "tables/a.csv"]
    (folder / "weights.json").write_text('{"w": [0.6]}\n')
    second = cell_key(folder)
    assert second != first
    (folder / "tables" / "b.csv").write_text("x\n2\n")  # a new file in a declared folder
    assert cell_key(folder) not in (first, second)


def test_a_declared_data_file_that_is_missing_is_refused_at_load(tmp_path):
    folder = plugin(tmp_path, {"energy.py": DATA_PLUGIN, "weights.json": "{}\n"})
    with pytest.raises(PluginError, match=r"declares data files that are not there: tables"):
        cell_key(folder)


def test_a_helper_installed_elsewhere_is_not_hashed_as_the_plugins(tmp_path, monkeypatch):
    """A name the plugin imports that an installed distribution provides (numpy) or that is
    loaded from outside the folder is not part of the plugin's identity."""
    elsewhere = plugin(tmp_path / "lib", {"idhelper.py": "SCALE = 1\n"})
    folder = plugin(tmp_path / "p", {"energy.py": ENERGY + "\nimport idhelper  # noqa\n"})
    (folder / "idhelper.py").write_text("SCALE = 2\n")  # shadowed by the one on sys.path first
    monkeypatch.syspath_prepend(str(elsewhere))
    import idhelper

    assert Path(idhelper.__file__).parent == elsewhere
    assert [label for label, _ in keys.local_files(folder / "energy.py")] == ["energy.py"]
