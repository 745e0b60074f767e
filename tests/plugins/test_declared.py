"""`slipbench list` reads installed plugins from their source, importing no detector."""

from __future__ import annotations

import json
import subprocess
import sys

from slipbench.engine import declared, registry


def _listed(*flags: str) -> dict:
    done = subprocess.run(
        [sys.executable, "-m", "slipbench", "list", "--json", *flags],
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(done.stdout)


def test_list_imports_no_detector_and_shows_what_importing_them_shows():
    code = (
        "import sys; from slipbench.app.cli import main; sys.argv = ['slipbench', 'list']\n"
        "try: main()\nexcept SystemExit: pass\n"
        "heavy = [m for m in sys.modules if m.split('.')[0] in ('scipy', 'sklearn', 'numba', "
        "'pandas', 'pywt') or m.startswith(('slipbench.detectors.', 'slipbench.protocols.'))]\n"
        "print('HEAVY', heavy, file=sys.stderr)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert "HEAVY []" in done.stderr, done.stderr[-2000:]
    read, checked = _listed(), _listed("--check")
    for kind in ("detectors", "protocols"):
        for fast, slow in zip(read[kind], checked[kind], strict=True):
            assert fast.pop("read") == "source" and slow.pop("read") == "import"
            for name, p in fast["parameters"].items():  # a library's list is shown as declared
                if p["constraint"].startswith("as declared: "):
                    slow["parameters"][name]["constraint"] = p["constraint"]
            assert fast == slow, fast["name"]


def test_a_plain_constraint_is_evaluated_and_a_computed_one_shown_as_declared(monkeypatch):
    # a plugin an earlier test of this process imported is described from its class: forget it
    monkeypatch.setattr(registry.detectors, "_loaded", {})
    found = registry.detectors.describe("wavelet-svm", check=False)
    assert found["parameters"]["level"] == {"default": 4, "constraint": "an int in [1, 12]"}
    wavelet = found["parameters"]["wavelet"]["constraint"]
    assert wavelet == "as declared: Options(tuple(pywt.wavelist(kind='discrete')))"
    tcn = registry.detectors.describe("tcn", check=False)["parameters"]  # ** of a base's dict
    assert tcn["batch_size"]["constraint"] == "an int in [1, 65536]"


def test_what_needs_running_code_falls_back_to_importing(tmp_path, monkeypatch):
    pkg = tmp_path / "labplug"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "computed.py").write_text(
        "from slipbench.base import BaseDetector\n"
        "import math\n"
        "class Computed(BaseDetector):\n"
        "    '''Uses a computed default.'''\n"
        "    def __init__(self, k=math.sqrt(2)):\n"
        "        self.k = k\n"
    )
    (pkg / "absent.py").write_text(
        "import no_such_module_slipbench\nfrom slipbench.base import BaseDetector\n"
        "class Absent(BaseDetector):\n    '''Needs a module not installed.'''\n"
    )
    (pkg / "plain.py").write_text(
        "from slipbench.base import BaseDetector\nfrom slipbench.params import Interval\n"
        "K = 3\n"
        "class Plain(BaseDetector):\n    '''A plain one.'''\n"
        "    requires = ('no_such_module_slipbench',)\n"
        "    _parameter_constraints = {'k': Interval(int, 1, 2 * K)}\n"
        "    def __init__(self, k=K):\n        self.k = k\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    base = ("slipbench.base", "BaseDetector")
    for target, why in (
        ("labplug.computed:Computed", "math.sqrt in labplug.computed is not a plain value"),
        ("labplug.absent:Absent", "imports no_such_module_slipbench, which is not installed"),
    ):
        try:
            declared.declaration(target, base)
        except declared.NeedsImport as exc:
            assert why in str(exc)
        else:
            raise AssertionError(f"{target} was read without its import")
    plain = declared.declaration("labplug.plain:Plain", base)
    assert plain["parameters"] == {"k": 3} and plain["description"] == "A plain one."
    assert plain["attributes"]["_parameter_constraints"] == {"k": "an int in [1, 6]"}
    assert plain["attributes"]["requires"] == ("no_such_module_slipbench",)
