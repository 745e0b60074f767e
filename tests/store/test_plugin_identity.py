"""The code identity of a folder plugin covers everything it runs: the helper modules and
packages beside it that it imports, and the data files it declares. A change to any of them
changes the cell key (the cell is computed anew); unchanged code keeps its key."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
import toys
from datagen import subset

from slipbench.base import BaseDetector
from slipbench.engine import plan, registry
from slipbench.engine.plan import Run
from slipbench.engine.runner import evaluate
from slipbench.errors import PluginError
from slipbench.protocol import Cell, Part
from slipbench.store import keys
from slipbench.store.results import ResultsStore

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
    keys._covered.cache_clear()
    keys._READ_AT_IMPORT.clear()


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


# loads a helper by path at import (no import statement shows it) and reads a table at import
BY_PATH = ENERGY + (
    "\nimport importlib.util as _u\n"
    "_spec = _u.spec_from_file_location('idbypath', Path(__file__).parent / 'bypath.py')\n"
    "_helper = _u.module_from_spec(_spec)\n"
    "_spec.loader.exec_module(_helper)\n"
    "_TABLE = (Path(__file__).parent / 'table.txt').read_text()\n"
)


def test_files_read_while_importing_join_the_identity(tmp_path):
    """A helper loaded with importlib from a path, and a file read at import, are seen by the
    audit hook: a change to either changes the key; another process sees the same files."""
    folder = plugin(tmp_path, {"energy.py": BY_PATH, "bypath.py": "K = 1\n", "table.txt": "a\n"})
    first = cell_key(folder)
    assert cell_key(folder) == first
    unit = next(u for u in keys._READ_AT_IMPORT if u.startswith("slipbench_plugin_energy"))
    assert [label for label, _ in keys._READ_AT_IMPORT[unit]] == [
        "read:bypath.py",
        "read:table.txt",
    ]
    (folder / "bypath.py").write_text("K = 2\n")
    second = cell_key(folder)
    assert second != first
    (folder / "table.txt").write_text("b\n")
    assert cell_key(folder) not in (first, second)


def test_a_file_read_at_import_outside_the_folder_warns(tmp_path):
    (tmp_path / "far.txt").write_text("x\n")
    text = ENERGY + "\n_FAR = (Path(__file__).parent.parent / 'far.txt').read_text()\n"
    folder = plugin(tmp_path / "p", {"energy.py": text})
    with pytest.warns(UserWarning, match=r"far\.txt while importing; it is outside"):
        cell_key(folder)


# reads an undeclared file beside it in fit: the key exists before the fit, so the row records
# the file's digest and a later run refits where it changed
READS_IN_FIT = ENERGY.replace(
    "    def _fit(self, x, y, seed):\n",
    "    def _fit(self, x, y, seed):\n"
    "        self.shift_ = float((Path(__file__).parent / 'shift.txt').read_text())\n",
)


@pytest.fixture(scope="module")
def index(small):
    rec = small.recordings
    return subset(small, rec["sensor_type"].eq("Nano17") & rec["sensor_instance"].eq("index"))


def _evaluate(folder: Path, index, out: Path):
    _forget()
    reg = registry.Registry("detector", BaseDetector, "slipbench.no-such-group")
    reg.add_folder(folder)
    from slipbench.protocols.window_size import WindowSize

    run = Run(reg.get("energy")(), WindowSize(windows=[50]))
    return evaluate(index, run, ResultsStore(out), jobs=0, progress=False)


def test_a_fit_that_reads_a_file_records_its_digest(tmp_path):
    import numpy as np

    from slipbench.engine.fitting import Job, TestSet, fit_and_test
    from slipbench.store.keys import changed_reads

    folder = plugin(tmp_path / "p", {"energy.py": READS_IN_FIT, "shift.txt": "0.5\n"})
    reg = registry.Registry("detector", BaseDetector, "slipbench.no-such-group")
    reg.add_folder(folder)
    x, y = np.linspace(0, 1, 200).reshape(20, 10), np.repeat([0, 1], 10)
    test = TestSet(x, y, np.arange(20) // 2)
    [(fields, _)] = fit_and_test(Job(reg.get("energy")(), 1, 1000.0, x, y, [test]))
    assert fields["status"] == "ok", fields["reason"]
    assert list(json.loads(fields["unkeyed_reads"])) == [str((folder / "shift.txt").resolve())]
    assert changed_reads(fields) == []
    (folder / "shift.txt").write_text("0.7\n")
    assert changed_reads(fields) == [str((folder / "shift.txt").resolve())]


@pytest.mark.slow  # three evaluations (~4 s on a loaded 2-core machine)
def test_a_file_read_in_fit_warns_and_a_change_refits(tmp_path, index):
    folder = plugin(tmp_path / "p", {"energy.py": READS_IN_FIT, "shift.txt": "0.5\n"})
    with pytest.warns(UserWarning, match=r"shift\.txt while fitting; it is not part"):
        rows = _evaluate(folder, index, tmp_path / "out")
    ok = rows[rows["status"] == "ok"].iloc[0]
    read = json.loads(ok["unkeyed_reads"])
    assert list(read) == [str((folder / "shift.txt").resolve())]
    assert "shift.txt, which is not part of the detector's code identity" in ok["warnings"]
    first = rows.set_index("key")["finished_at"]

    again = _evaluate(folder, index, tmp_path / "out").set_index("key")["finished_at"]
    assert again.equals(first)  # unchanged: every cell reused

    (folder / "shift.txt").write_text("0.7\n")
    with pytest.warns(UserWarning, match=r"shift\.txt changed since its cells were computed"):
        changed = _evaluate(folder, index, tmp_path / "out").set_index("key")["finished_at"]
    assert list(changed.index) == list(first.index)  # same keys: the key never held the file
    refitted = rows.set_index("key")["status"] == "ok"
    assert (changed[refitted] != first[refitted]).all()


def test_a_plugin_that_reads_nothing_records_nothing(tmp_path):
    import numpy as np

    from slipbench.engine.fitting import Job, TestSet, fit_and_test

    folder = plugin(tmp_path / "p", {"energy.py": ENERGY})
    reg = registry.Registry("detector", BaseDetector, "slipbench.no-such-group")
    reg.add_folder(folder)
    x, y = np.linspace(0, 1, 200).reshape(20, 10), np.repeat([0, 1], 10)
    [(fields, _)] = fit_and_test(Job(reg.get("energy")(), 1, 1000.0, x, y, [TestSet(x, y, y)]))
    assert fields["status"] == "ok" and "unkeyed_reads" not in fields


def test_distribution_metadata_is_no_plugins_data(tmp_path):
    """Entry points read through importlib.metadata (an editable install's egg-info beside the
    code, a dist-info) are no file a fit depends on: no warning, no digest."""
    from slipbench.store.reads import plugin_files

    files = []
    for folder in ("slipbench.egg-info", "pkg-1.0.dist-info", "plugins"):
        (tmp_path / folder).mkdir()
        files.append(tmp_path / folder / "entry_points.txt")
        files[-1].write_text("[slipbench.detectors]\n")
    assert plugin_files({str(f) for f in files}) == [files[2].resolve()]


def _own(folder: Path, name: str = "energy") -> str:
    """A plugin's own code identity as a fresh process takes it."""
    _forget()
    keys._slipbench_closure.cache_clear()
    reg = registry.Registry("detector", BaseDetector, "slipbench.no-such-group")
    reg.add_folder(folder)
    return keys.own_code_identity(reg.get(name))


def test_a_built_in_detectors_own_code_is_its_file_and_the_contract_it_uses():
    """What a bench's calibration is keyed on: holweg's module and the slipbench modules it
    imports (the contract), not the engine, the statistics or the reports."""
    from slipbench.detectors.bandpass import BandPass
    from slipbench.detectors.holweg import Holweg

    file = Path(sys.modules[Holweg.__module__].__file__).resolve()
    closure = dict(keys._slipbench_closure(file))
    assert {"slipbench.base", "slipbench.spectra", "slipbench.params"} <= set(closure)
    assert not any(m.split(".")[1] in ("engine", "stats", "report", "app") for m in closure if m)
    assert keys.own_code_identity(Holweg) != keys.own_code_identity(BandPass)
    assert keys.own_code_identity(Holweg) != keys.code_identity(Holweg)  # narrower
    assert keys.own_code_identity(Holweg) == keys.own_code_identity(Holweg)


def test_a_plugins_own_code_changes_with_its_files(tmp_path):
    folder = tmp_path / "plugins"
    folder.mkdir()
    (folder / "energy.py").write_text(ENERGY)
    first = _own(folder)
    assert first == _own(folder)
    (tmp_path / "elsewhere.py").write_text("x = 1\n")  # not beside it: not its code
    assert _own(folder) == first
    (folder / "energy.py").write_text(ENERGY + "\n# a comment is a change of its file\n")
    assert _own(folder) != first
