"""The engine keeps the boundary it asks of plugins: it never imports the built-in plugins, and
no module imports itself back through another (no import cycles)."""

from __future__ import annotations

import ast
from pathlib import Path

import slipbench
import slipbench.detectors
import slipbench.protocols

PACKAGES = {
    "slipbench": Path(slipbench.__file__).parent,
    "slipbench.detectors": Path(slipbench.detectors.__file__).parent,
    "slipbench.protocols": Path(slipbench.protocols.__file__).parent,
}


def _modules() -> dict[str, Path]:
    out = {}
    for package, folder in PACKAGES.items():
        for path in folder.glob("*.py"):
            out[package if path.stem == "__init__" else f"{package}.{path.stem}"] = path
    return out


def _imports(name: str, path: Path, known: set[str]) -> set[str]:
    """Modules of slipbench that ``name`` imports, at module level or inside functions (not
    those imported for type hints alone, under ``if TYPE_CHECKING:``, which never run)."""
    package = name if path.stem == "__init__" else name.rpartition(".")[0]
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and getattr(node.test, "id", None) == "TYPE_CHECKING":
            node.body = []
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(
                    package.split(".")[: len(package.split(".")) - node.level + 1]
                    + ([base] if base else [])
                )
            targets = [base] + [f"{base}.{a.name}" for a in node.names]
        else:
            continue
        found |= {t for t in targets if t in known and t != name}
    return found


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    return {name: _imports(name, path, set(modules)) for name, path in modules.items()}


def test_the_engine_never_imports_the_builtin_plugins():
    engine = {
        n: deps
        for n, deps in _graph().items()
        if not n.startswith(("slipbench.detectors", "slipbench.protocols"))
    }
    leaks = {
        n: sorted(d for d in deps if d.startswith(("slipbench.detectors", "slipbench.protocols")))
        for n, deps in engine.items()
    }
    assert not {n: d for n, d in leaks.items() if d}, (
        "the engine imports plugins; it must reach them through the registry"
    )


def test_a_protocol_never_imports_another_plugin():
    graph = _graph()
    for name, deps in graph.items():
        if name.startswith(("slipbench.detectors.", "slipbench.protocols.")):
            family = name.rsplit(".", 1)[0]
            others = [
                d
                for d in deps
                if d.startswith(("slipbench.detectors.", "slipbench.protocols."))
                and not d.startswith(name.rsplit("_", 1)[0])
                and d.rsplit(".", 1)[0] != family
            ]
            assert not others, f"{name} imports another plugin: {others}"


def test_no_import_cycles():
    graph = _graph()
    state: dict[str, int] = {}
    path: list[str] = []

    def visit(node: str) -> None:
        state[node] = 1
        path.append(node)
        for dep in sorted(graph[node]):
            if state.get(dep) == 1:
                cycle = path[path.index(dep) :] + [dep]
                raise AssertionError("import cycle: " + " -> ".join(cycle))
            if dep not in state:
                visit(dep)
        path.pop()
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node)


def test_the_graph_sees_imports():
    """The checks above would pass on an empty graph: make sure the parser finds real imports."""
    graph = _graph()
    assert "slipbench.base" in graph["slipbench.engine.registry"]
    assert "slipbench.protocol" in graph["slipbench.protocols.window_size"]
    assert "slipbench.detectors.lstm_kernels" in graph["slipbench.detectors.lstm"]
