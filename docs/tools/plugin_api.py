"""The plugin API reference, ``docs/reference/plugin-api.md``, written from the docstrings of what a
plugin may use: ``python docs/tools/plugin_api.py > docs/reference/plugin-api.md``.

Signatures and text come from the code; each entry's example is kept here, in ``ENTRIES``, and
the examples run in order as one script (``tests/testing/test_apidoc.py`` runs them and checks
that the committed page is what this module writes, so the page cannot drift from the code).
"""

from __future__ import annotations

import importlib
import inspect
import re
import sys
import textwrap
from dataclasses import dataclass
from typing import Any

PAGE = "docs/reference/plugin-api.md"


@dataclass(frozen=True)
class Entry:
    """One documented name: ``module:qualname``, and an example that runs after the ones
    before it (they share one namespace, as a reader's session would)."""

    target: str
    example: str


SETUP = """\
import numpy as np
from slipbench.base import BaseDetector
from slipbench.params import Interval


class Energy(BaseDetector):
    \"\"\"Mean absolute signal above a training quantile.\"\"\"

    _parameter_constraints = {"quantile": Interval(float, 0.0, 1.0)}

    def __init__(self, quantile=0.5):
        self.quantile = quantile

    def _fit(self, x, y, seed):
        self.cut_ = float(np.quantile(np.abs(x).mean(axis=1), self.quantile))

    def _predict_proba(self, x):
        return (np.abs(x).mean(axis=1) > self.cut_).astype(float)


rng = np.random.default_rng(0)  # the examples' own data; a plugin draws with slipbench.seeding
y = np.tile(np.array([0, 1], np.int8), 50)
x = (rng.normal(size=(100, 50)) * (1 + 2 * y[:, None])).astype(np.float32)
"""

SECTIONS: list[tuple[str, str, list[Entry]]] = [
    (
        "Detectors",
        "A detector subclasses `BaseDetector`, stores its keyword parameters in `__init__` and "
        "implements `_fit` and `_predict_proba`; the base class validates and owns the rest. "
        "The examples below use the `Energy` detector and the windows `x`, labels `y` defined "
        "in [Setup](#setup).",
        [
            Entry("slipbench.base:BaseDetector", "detector = Energy(quantile=0.6)\n"),
            Entry(
                "slipbench.base:BaseDetector._fit",
                "# in a subclass: learn from x (n_windows, window_length) float32, y 0/1 int8\n"
                "# self.cut_ = float(np.quantile(np.abs(x).mean(axis=1), self.quantile))\n",
            ),
            Entry(
                "slipbench.base:BaseDetector._predict_proba",
                "# in a subclass: one probability of slip per window, in [0, 1]\n"
                "# return (np.abs(x).mean(axis=1) > self.cut_).astype(float)\n",
            ),
            Entry(
                "slipbench.base:BaseDetector.fit",
                "detector.fit(x, y, sampling_rate=1000.0, seed=0)\n"
                "assert detector.window_length_ == 50\n",
            ),
            Entry(
                "slipbench.base:BaseDetector.fit_lockstep",
                "from slipbench.base import FitJob\n"
                "\n"
                "jobs = [FitJob(x, y, seed=0), FitJob(x[::-1], y[::-1], seed=1)]\n"
                "pair = Energy.fit_lockstep([Energy(quantile=0.6), Energy(quantile=0.9)], jobs)\n"
                "assert pair[1].cut_ == Energy(quantile=0.9).fit(x[::-1], y[::-1], seed=1).cut_\n",
            ),
            Entry(
                "slipbench.base:BaseDetector.lockstep_key",
                "assert Energy(quantile=0.6).lockstep_key(50) != Energy(quantile=0.9).lockstep_key(50)\n"
                "assert Energy().lockstep_key(50) == Energy().lockstep_key(50)\n",
            ),
            Entry(
                "slipbench.base:BaseDetector.predict_proba",
                "scores = detector.predict_proba(x)  # (100,) in [0, 1]\n",
            ),
            Entry(
                "slipbench.base:BaseDetector.predict",
                "accuracy = (detector.predict(x) == y).mean()\n",
            ),
            Entry(
                "slipbench.base:BaseDetector.fitted_choices",
                "class ReportedEnergy(Energy):\n"
                "    def fitted_choices(self):\n"
                '        return {"threshold": self.cut_}  # a row\'s "What fitting chose"\n'
                "\n"
                "\n"
                'assert "threshold" in ReportedEnergy().fit(x, y).fitted_choices()\n',
            ),
            Entry(
                "slipbench.base:BaseDetector.overrides",
                "class FewWindowsEnergy(Energy):\n"
                "    def overrides(self):  # the fit ran the median: too few windows for the tail\n"
                "        if len(self.seen_) < 1000 and self.quantile > 0.9:\n"
                '            return {"quantile": (0.5, f"{len(self.seen_)} windows")}\n'
                "        return {}\n"
                "\n"
                "    def _fit(self, x, y, seed):\n"
                "        self.seen_ = x\n"
                "        super()._fit(x, y, seed)\n"
                "\n"
                "\n"
                'assert FewWindowsEnergy(quantile=0.95).fit(x, y).overrides() == {"quantile": (0.5, "100 windows")}\n',
            ),
            Entry(
                "slipbench.base:BaseDetector.report_progress",
                "class PatientEnergy(Energy):\n"
                "    def _fit(self, x, y, seed):\n"
                "        for epoch in range(3):  # a long fit says how far it has come\n"
                "            self.report_progress(epoch + 1, 3, loss=1.0 / (epoch + 1))\n"
                "        super()._fit(x, y, seed)\n"
                "\n"
                "\n"
                "PatientEnergy().fit(x, y)  # nobody listens here: each report costs one call\n",
            ),
            Entry(
                "slipbench.base:BaseDetector.streamer",
                "stream = detector.streamer(hop=10, threshold=0.5)\n"
                "scores, decisions = stream.push(x[0])  # 50 samples: the first window\n"
                "assert len(scores) == 1\n",
            ),
            Entry(
                "slipbench.base:BaseDetector._streamer",
                "# override to return a faster Streamer subclass; it must give predict_proba's\n"
                "# scores: return MyStreamer(self, hop, threshold)\n",
            ),
            Entry(
                "slipbench.base:BaseDetector.save",
                "import tempfile, pathlib\n"
                'saved = pathlib.Path(tempfile.mkdtemp()) / "energy.npz"\n'
                "detector.save(saved)\n",
            ),
            Entry(
                "slipbench.base:BaseDetector.load",
                "again = Energy.load(saved)\n"
                "assert (again.predict_proba(x) == detector.predict_proba(x)).all()\n",
            ),
            Entry(
                "slipbench.base:BaseDetector.benchmark",
                "assert Energy.benchmark(length=50, seconds=0.1) is None  # none declared\n",
            ),
            Entry(
                "slipbench.base:clone",
                "from slipbench.base import clone\n"
                "fresh = clone(detector)  # same parameters, not fitted\n",
            ),
            Entry(
                "slipbench.base:NotFittedError",
                "from slipbench.base import NotFittedError\n"
                "try:\n"
                "    Energy().predict_proba(x)\n"
                "except NotFittedError as exc:\n"
                "    print(exc)\n",
            ),
        ],
    ),
    (
        "Streaming",
        "Every fitted detector streams; a detector with state across pushes (the LSTM) returns "
        "its own `Streamer` subclass from `_streamer`.",
        [
            Entry(
                "slipbench.base:Streamer",
                "from slipbench.base import Streamer\n"
                "stream = Streamer(detector, hop=5)  # what the default _streamer returns\n",
            ),
            Entry(
                "slipbench.base:Streamer.push",
                "scores, decisions = stream.push(x[0][:30])  # no window complete yet\n"
                "scores, decisions = stream.push(x[0][30:])  # sample 49 completes the first\n"
                "assert len(scores) == 1 and stream.n_samples == 50\n",
            ),
            Entry(
                "slipbench.base:Streamer._push",
                "# in a subclass: x holds the new samples, n the scores they complete\n"
                "# (the last n windows ending at or before the newest sample)\n",
            ),
            Entry(
                "slipbench.base:Streamer.threshold",
                "stream.threshold = 0.9  # decisions from the next push on\n",
            ),
            Entry(
                "slipbench.base:Streamer.reset", "stream.reset()\nassert stream.n_samples == 0\n"
            ),
            Entry(
                "slipbench.base:stream_scores",
                "from slipbench.base import stream_scores\n"
                "ends, scores = stream_scores(detector, x[:4].ravel(), hop=50)\n"
                "assert len(scores) == 4\n",
            ),
        ],
    ),
    (
        "PyTorch detectors",
        "`slipbench.torch.TorchDetector` (with `pip install 'slipbench[torch]'`) owns training, "
        "validation by whole trials, early stopping, seeding, the device, saving and streaming; "
        "a plugin writes `build` and its own parameters.",
        [
            Entry(
                "slipbench.torch.detector:TorchDetector",
                "from torch import nn\n"
                "from slipbench.torch import TorchDetector\n\n"
                "class TinyCNN(TorchDetector):\n"
                "    _parameter_constraints = {\n"
                '        **TorchDetector.TRAINING_CONSTRAINTS, "filters": Interval(int, 1, 64)\n'
                "    }\n\n"
                "    def __init__(self, filters=8, batch_size=64, learning_rate=1e-2, max_epochs=20,\n"
                '                 patience=3, validation_fraction=0.2, device="auto"):\n'
                "        super().__init__(batch_size, learning_rate, max_epochs, patience,\n"
                "                         validation_fraction, device)\n"
                "        self.filters = filters\n\n"
                "    def build(self, window_length, n_channels):\n"
                "        return nn.Sequential(\n"
                "            nn.Conv1d(n_channels, self.filters, 5, padding=2), nn.ReLU(),\n"
                "            nn.AdaptiveAvgPool1d(1), nn.Flatten(), nn.Linear(self.filters, 1))\n\n"
                "cnn = TinyCNN(max_epochs=2).fit(x, y, seed=0, groups=np.arange(100) // 10)\n"
                'assert cnn.fitted_choices()["validation_by"] == "trial"\n',
            ),
            Entry(
                "slipbench.torch.detector:TorchDetector.build",
                "net = TinyCNN().build(50, 1)  # windows (batch, 1, 50) -> one logit each\n",
            ),
        ],
    ),
    (
        "Parameters",
        "Detectors and protocols share scikit-learn's parameter protocol: keyword arguments of "
        "`__init__`, stored under their own names, checked against `_parameter_constraints` "
        "before any work starts.",
        [
            Entry(
                "slipbench.params:Parameterized.get_params",
                'assert detector.get_params() == {"quantile": 0.6}\n',
            ),
            Entry(
                "slipbench.params:Parameterized.set_params",
                "detector.set_params(quantile=0.7)\n",
            ),
            Entry(
                "slipbench.params:Parameterized.validate_params",
                "from slipbench.errors import UsageError\n"
                "try:\n"
                "    Energy(quantile=3).validate_params()\n"
                "except UsageError as exc:\n"
                "    print(exc)  # The 'quantile' parameter of Energy must be ...\n",
            ),
            Entry(
                "slipbench.params:Interval",
                "from slipbench.params import Interval\n"
                "assert Interval(int, 1, None).check(5) and not Interval(float, 0, 1).check(2)\n",
            ),
            Entry(
                "slipbench.params:Options",
                "from slipbench.params import Options\n"
                'assert Options(("plain", "lag")).check("lag")\n',
            ),
            Entry(
                "slipbench.params:Band",
                "from slipbench.params import Band\n"
                "assert Band().check(None) and Band().check((39, 100))\n",
            ),
            Entry(
                "slipbench.params:Sequence",
                "from slipbench.params import Sequence, WindowLength\n"
                'assert Sequence(WindowLength()).check([25, "50ms"])\n',
            ),
            Entry(
                "slipbench.params:WindowLength",
                'assert WindowLength().check("50ms") and not WindowLength(low=5).check(3)\n',
            ),
            Entry(
                "slipbench.params:window_samples",
                "from slipbench.params import window_samples\n"
                'assert window_samples("50ms", 1000.0) == 50 and window_samples(64, 500.0) == 64\n',
            ),
        ],
    ),
    (
        "Shared detector pieces",
        "What the built-in detectors share, public for plugins (`slipbench.spectra`).",
        [
            Entry(
                "slipbench.spectra:amplitude_spectrum",
                "from slipbench.spectra import amplitude_spectrum\n"
                "freqs, amps = amplitude_spectrum(x, sampling_rate=1000.0)  # per window\n",
            ),
            Entry(
                "slipbench.spectra:best_threshold",
                "from slipbench.spectra import best_threshold\n"
                "energy = np.abs(x).mean(axis=1)\n"
                "threshold, direction, separation = best_threshold(energy, y)\n"
                "called = direction * (energy - threshold) > 0\n",
            ),
            Entry(
                "slipbench.spectra:grow_band",
                "from slipbench.spectra import grow_band\n"
                "inside = np.array([False, True, True, True, False])\n"
                "assert grow_band(inside, peak=2) == (1, 3)\n",
            ),
            Entry(
                "slipbench.spectra:logistic",
                "from slipbench.spectra import logistic\n"
                "assert logistic(np.array([0.0]))[0] == 0.5\n",
            ),
        ],
    ),
    (
        "Protocols",
        "A protocol turns the recordings' metadata (one row per recording, columns as in "
        "[Datasets](datasets.md#recordingsparquet-one-row-per-recording)) into cells; it never sees samples and never trains.",
        [
            Entry(
                "slipbench.protocol:BaseProtocol",
                "from slipbench.protocol import BaseProtocol, Layout, sensor_pairs, window_cells\n"
                "from slipbench.protocol import Cell, Part, Presentation\n"
                "\n"
                "\n"
                "class OneWindow(BaseProtocol):\n"
                '    """Each unit at one window, trained and tested on itself."""\n'
                "\n"
                '    layout = Layout(rows=("sensor_type",), column="window")\n'
                '    presentation = Presentation("Accuracy per unit.", title="One window")\n'
                "\n"
                "    def cells(self, recordings):\n"
                "        for sensor in sensor_pairs(recordings):\n"
                "            for window, key, skip in window_cells(recordings, sensor, [50]):\n"
                "                yield Cell(\n"
                '                    key={"sensor_type": sensor[0], "sensor_instance": sensor[1], **key},\n'
                '                    train=Part((sensor,), "train"),\n'
                '                    test=Part((sensor,), "test"),\n'
                "                    window=window,\n"
                "                    skip=skip,\n"
                "                )\n",
            ),
            Entry(
                "slipbench.protocol:BaseProtocol.cells",
                "from slipbench.testing import toy_dataset\n"
                "recordings = toy_dataset().recordings\n"
                "cells = list(OneWindow().cells(recordings))\n",
            ),
            Entry(
                "slipbench.protocol:BaseProtocol.columns",
                "# def columns(self, recordings):\n"
                '#     return {"fast": (recordings["speed"] > 10).to_numpy()}  # for Part(where=...)\n',
            ),
            Entry(
                "slipbench.protocol:BaseProtocol.why_no_cells",
                "print(OneWindow().why_no_cells(recordings))\n",
            ),
            Entry(
                "slipbench.protocol:Cell",
                "cell = cells[0]\nassert cell.window == 50 and cell.train.side == 'train'\n",
            ),
            Entry(
                "slipbench.protocol:Part",
                'Part((("Nano17", "index"),), "test", where=(("material", "!=", "felt"),))\n',
            ),
            Entry(
                "slipbench.protocol:Layout",
                'Layout(rows=("sensor_type",), column="material", pair="training")\n',
            ),
            Entry(
                "slipbench.protocol:Presentation",
                'Presentation("Accuracy with and without each material.", figure="with-without")\n',
            ),
            Entry(
                "slipbench.protocol:HoldoutProtocol",
                "from slipbench.protocol import HoldoutProtocol\n"
                "\n"
                "\n"
                "class MaterialsHeldOut(HoldoutProtocol):\n"
                '    """Each material with and without training on it (option: window)."""\n'
                "\n"
                '    holdout_column = "material"\n'
                '    layout = Layout(rows=("sensor_type",), column="material", pair="training")\n'
                "    presentation = Presentation(\n"
                '        "Accuracy with and without each material.", figure="with-without"\n'
                "    )\n"
                "\n"
                "    def levels(self, recordings):\n"
                '        return sorted(recordings["material"].dropna().unique())\n',
            ),
            Entry(
                "slipbench.protocol:HoldoutProtocol.levels",
                "materials = MaterialsHeldOut().levels(recordings)\n",
            ),
            Entry(
                "slipbench.protocol:holdout_cells",
                "from slipbench.protocol import holdout_cells\n"
                'pairs = list(holdout_cells(recordings, "material", materials[:1], window=50))\n'
                'assert {c.key["training"] for c in pairs} == {"with", "without"}\n',
            ),
            Entry(
                "slipbench.protocol:window_cells",
                "sensor = sensor_pairs(recordings)[0]\n"
                'for window, key, skip in window_cells(recordings, sensor, [25, "50ms"]):\n'
                "    print(window, key, skip)\n",
            ),
            Entry(
                "slipbench.protocol:sensor_pairs",
                "assert all(len(pair) == 2 for pair in sensor_pairs(recordings))\n",
            ),
            Entry(
                "slipbench.protocol:unit_rate",
                "from slipbench.protocol import unit_rate\n"
                "print(unit_rate(recordings, sensor), 'Hz')\n",
            ),
        ],
    ),
    (
        "Random draws",
        "Every random draw comes from the run's seed and a named stream, so no two consumers "
        "share draws. A detector's `_fit` receives its seed already drawn from the stream "
        "`detector`.",
        [
            Entry(
                "slipbench.seeding:rng_for",
                "from slipbench.seeding import rng_for\n"
                'draws = rng_for(0, "my-detector-init", 50).normal(size=3)  # seed, stream, key\n',
            ),
            Entry(
                "slipbench.seeding:seed_int",
                "from slipbench.seeding import seed_int\n"
                'random_state = seed_int(0, "my-detector-forest")  # for scikit-learn\n',
            ),
        ],
    ),
    (
        "Errors",
        "What a plugin may raise, and what slipbench makes of it. Any other exception in "
        "`_fit` or `_predict_proba` fails its cell with the plugin's id and the error; the run "
        "goes on.",
        [
            Entry(
                "slipbench.errors:SlipbenchError",
                "from slipbench.errors import SlipbenchError\n"
                "assert issubclass(NotFittedError, SlipbenchError)\n",
            ),
            Entry(
                "slipbench.errors:UsageError",
                "from slipbench.errors import UsageError\n"
                '# raise UsageError("band must lie below Nyquist (500 Hz), got [400, 600]")\n',
            ),
            Entry(
                "slipbench.errors:DataError",
                "from slipbench.errors import DataError\n"
                '# raise DataError("recording 12 has no slip onset")\n',
            ),
            Entry(
                "slipbench.errors:PluginError",
                "from slipbench.errors import PluginError\n"
                "# raise PluginError(\"energy: needs aeon; pip install 'slipbench[minirocket]'\")\n",
            ),
            Entry(
                "slipbench.errors:DetectorOutputError",
                "from slipbench.errors import DetectorOutputError\n"
                "assert issubclass(DetectorOutputError, PluginError)\n",
            ),
        ],
    ),
    (
        "Conformance suite",
        "`slipbench.testing` checks a plugin the way slipbench will use it.",
        [
            Entry(
                "slipbench.testing:parametrize_with_checks",
                "from slipbench.testing import parametrize_with_checks\n"
                "\n"
                "\n"
                "@parametrize_with_checks([Energy(), OneWindow()])\n"
                "def test_conformance(plugin, check):\n"
                "    check(plugin)\n",
            ),
            Entry(
                "slipbench.testing:check_detector",
                "from slipbench.testing import check_detector\n"
                "check_detector(Energy())  # AssertionError naming the first check that fails\n",
            ),
            Entry(
                "slipbench.testing:check_protocol",
                "from slipbench.testing import check_protocol\n"
                "check_protocol(OneWindow(), toy_dataset())\n",
            ),
            Entry(
                "slipbench.testing:toy_dataset",
                "assert len(toy_dataset().recordings) > 0\n",
            ),
        ],
    ),
]


def resolve(target: str) -> Any:
    module, _, qualname = target.partition(":")
    obj: Any = importlib.import_module(module)
    for part in qualname.split("."):
        obj = inspect.getattr_static(obj, part) if inspect.isclass(obj) else getattr(obj, part)
    if isinstance(obj, (classmethod, staticmethod)):
        obj = obj.__func__
    return obj


def _annotation(value: Any) -> str:
    text = value if isinstance(value, str) else inspect.formatannotation(value)
    return text.replace("np.ndarray", "ndarray").replace("_Self", "Self")


def signature(target: str, obj: Any) -> str:
    """``name(params) -> return`` with annotations as the code writes them."""
    name = target.partition(":")[2]
    if isinstance(obj, property):
        getter = obj.fget
        ret = inspect.signature(getter).return_annotation if getter else inspect.Signature.empty
        return f"{name}: {_annotation(ret)}  (property)"
    if inspect.isclass(obj) and issubclass(obj, BaseException):
        return f"class {name}({obj.__bases__[0].__name__})"
    sig = inspect.signature(obj)
    params, previous = [], None
    for p in sig.parameters.values():
        if p.name in ("self", "cls") and previous is None:
            previous = p.kind
            continue
        if p.kind is p.KEYWORD_ONLY and previous not in (p.KEYWORD_ONLY, p.VAR_POSITIONAL):
            params.append("*")
        stars: dict[Any, str] = {p.VAR_POSITIONAL: "*", p.VAR_KEYWORD: "**"}
        text = stars.get(p.kind, "") + p.name
        if p.annotation is not p.empty:
            text += f": {_annotation(p.annotation)}"
        if p.default is not p.empty:
            text += (" = " if p.annotation is not p.empty else "=") + repr(p.default)
        params.append(text)
        previous = p.kind
    if inspect.isclass(obj):  # the base, then the constructor where it takes arguments
        base = obj.__bases__[0]
        head = f"class {name}" + ("" if base is object else f"({base.__name__})")
        return head + (f"\n{name}({', '.join(params)})" if params else "")
    ret = "" if sig.return_annotation is sig.empty else f" -> {_annotation(sig.return_annotation)}"
    return f"{name}({', '.join(params)}){ret}"


def markdown(doc: str) -> str:
    """reST of the docstrings to Markdown: ``code`` and :role:`name` to `code`; ``::`` blocks
    to fenced code; numpydoc section underlines to bold headings."""
    doc = re.sub(r":(?:meth|class|func|mod|attr):`~?([^`]+)`", r"`\1`", doc)
    doc = re.sub(r"``([^`]+)``", r"`\1`", doc)
    lines, out, i = doc.splitlines(), [], 0
    while i < len(lines):
        line = lines[i]
        if i + 1 < len(lines) and re.fullmatch(r"-{3,}", lines[i + 1].strip()) and line.strip():
            out += [f"**{line.strip()}**", ""]
            i += 2
            continue
        if line.rstrip().endswith("::") and i + 1 < len(lines):
            head = line.rstrip()[:-1].rstrip()
            out.append(head if head.endswith(":") or not head else head + ":")
            block, i = [], i + 1
            while i < len(lines) and (not lines[i].strip() or lines[i].startswith("    ")):
                block.append(lines[i])
                i += 1
            out += ["", "```python", textwrap.dedent("\n".join(block)).strip("\n"), "```", ""]
            continue
        out.append(line)
        i += 1
    return "\n".join(out).strip()


def anchor(target: str) -> str:
    return re.sub(r"[^a-z0-9_-]", "", target.partition(":")[2].lower().replace(".", "-"))


def entries() -> list[Entry]:
    return [e for _, _, group in SECTIONS for e in group]


def render() -> str:
    """The whole page."""
    out = [
        "# The plugin API",
        "",
        "Every class, function and hook a detector or protocol plugin may use, with its "
        "signature and an example. Generated from the docstrings by "
        "`python docs/tools/plugin_api.py > docs/reference/plugin-api.md`; do not edit by hand "
        "(`tests/testing/test_apidoc.py` fails when the page and the code disagree, and runs "
        "the examples below in order, as one script). How to register a plugin and what the "
        "built-ins do: [Writing plugins](../guides/plugins.md).",
        "",
    ]
    for title, _, group in SECTIONS:
        out.append(f"- [{title}](#{title.lower().replace(' ', '-')}): ")
        out[-1] += ", ".join(
            f"[`{e.target.partition(':')[2]}`](#{anchor(e.target)})" for e in group
        )
    out += ["", "## Setup", "", "The examples below start from this:", "", "```python"]
    out += [SETUP.rstrip("\n"), "```", ""]
    for title, intro, group in SECTIONS:
        out += [f"## {title}", "", intro, ""]
        for e in group:
            obj = resolve(e.target)
            doc = inspect.getdoc(obj.fget if isinstance(obj, property) else obj)
            if not doc:
                raise ValueError(f"{e.target} has no docstring: the page is made from them")
            module, _, name = e.target.partition(":")
            out += [
                f'<a id="{anchor(e.target)}"></a>',
                f"### `{name}`",
                "",
                f"`{module}`",
                "",
                "```python",
                signature(e.target, obj),
                "```",
                "",
                markdown(doc),
                "",
                "Example:",
                "",
                "```python",
                e.example.rstrip("\n"),
                "```",
                "",
            ]
    return "\n".join(out).rstrip("\n") + "\n"


def script() -> str:
    """The page's examples as one script, in the page's order."""
    return SETUP + "".join(f"\n# {e.target}\n{e.example}" for e in entries())


if __name__ == "__main__":
    sys.stdout.write(render())
