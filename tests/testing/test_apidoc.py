"""docs/reference/plugin-api.md: written from the docstrings by docs/tools/plugin_api.py, never by hand;
every public hook a plugin uses is on it, with a docstring and an example that runs."""

from __future__ import annotations

import inspect
import re
import subprocess
import sys
from pathlib import Path

import plugin_api as apidoc  # docs/tools, on pytest's pythonpath
import pytest

from slipbench import base, params, protocol, spectra

ROOT = Path(__file__).resolve().parents[2]


def test_committed_page_is_what_the_generator_writes():
    page = (ROOT / apidoc.PAGE).read_text()
    assert page == apidoc.render(), (
        "docs/reference/plugin-api.md is stale: python docs/tools/plugin_api.py > docs/reference/plugin-api.md"
    )


def test_page_covers_every_hook_a_plugin_uses():
    documented = {e.target for e in apidoc.entries()}
    must = {
        "slipbench.base:BaseDetector.fitted_choices",
        "slipbench.spectra:best_threshold",
        "slipbench.params:Parameterized.get_params",
        "slipbench.testing:parametrize_with_checks",
        "slipbench.testing:check_protocol",
        "slipbench.seeding:rng_for",
        "slipbench.protocol:Cell",
        "slipbench.protocol:Part",
        "slipbench.protocol:HoldoutProtocol",
        "slipbench.base:Streamer",
    }
    assert must <= documented
    # every public method of the plugin base classes and every public function of the shared
    # modules, so a new one cannot be left off
    for cls in (base.BaseDetector, base.Streamer, protocol.BaseProtocol, protocol.HoldoutProtocol):
        for name, member in vars(cls).items():
            if callable(member) and not name.startswith("_"):
                owner = f"{cls.__module__}:{cls.__qualname__}.{name}"
                inherited = f"slipbench.protocol:BaseProtocol.{name}"
                assert owner in documented or inherited in documented, owner
    for module in (spectra, params):
        for name, obj in vars(module).items():
            if inspect.isfunction(obj) and obj.__module__ == module.__name__:
                if not name.startswith("_") and name not in (
                    "parse_ms",
                    "param_names",
                    "param_defaults",
                ):
                    assert f"{module.__name__}:{name}" in documented, name
    for e in apidoc.entries():
        obj = apidoc.resolve(e.target)
        assert inspect.getdoc(obj.fget if isinstance(obj, property) else obj), e.target


def test_signatures_show_keyword_only_and_defaults():
    assert apidoc.signature("slipbench.base:BaseDetector.fit", base.BaseDetector.fit) == (
        "BaseDetector.fit(x: Any, y: Any, *, sampling_rate: float = 1000.0, seed: int = 0,"
        " groups: Any = None)"
        " -> BaseDetector"
    )
    assert apidoc.signature("slipbench.spectra:best_threshold", spectra.best_threshold) == (
        "best_threshold(values: ndarray, y: ndarray) -> tuple[float, int, float]"
    )


def test_markdown_turns_rest_into_markdown():
    text = apidoc.markdown(
        "Uses ``x`` and :meth:`fit`.\n\nReturns\n-------\nA block::\n\n    a = 1\n"
    )
    assert text == "Uses `x` and `fit`.\n\n**Returns**\n\nA block:\n\n```python\na = 1\n```"


def test_the_plugins_guide_links_the_page():
    guide = (ROOT / "docs" / "guides" / "plugins.md").read_text()
    assert re.search(r"\]\(\.\./reference/plugin-api\.md\)", guide)


@pytest.mark.slow
def test_examples_run_in_order(tmp_path):
    script = tmp_path / "examples.py"
    script.write_text(apidoc.script())
    done = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr[-3000:]


def test_examples_compile():
    compile(apidoc.script(), "examples.py", "exec")
