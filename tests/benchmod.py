"""Benchmark scripts (``benchmarks/*.py``) imported by tests, once per process: a worker pool's
tasks pickle by module name, so two test files must share one module object, not load two."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
if (
    str(BENCHMARKS) not in sys.path
):  # the studies' package (benchmarks/studies), as the scripts see it
    sys.path.insert(0, str(BENCHMARKS))


def load(name: str) -> ModuleType:
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, BENCHMARKS / f"{name}.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module
