"""The package's shape, read from the source with `ast` (nothing is imported): the wings import
only downwards, no module imports itself back through others, the top level stays small, and the
built-in plugins reach the package through the plugin contract alone.

The wings, top to bottom (a wing may import its own wing, any wing below it, and the contract)::

    app, testing
    report, analysis
    history
    engine, gate
    stats, stream
    data, store, torch
    contract (the modules directly in slipbench/, at most 10: base, protocol, params, spectra,
              errors, vocabulary, seeding, atomic)

The plugin API is the contract and ``torch`` (TorchDetector, a base class for detectors written
in PyTorch): built-in plugins import nothing else of the package.

The report sits above the engine but imports nothing of it (``APART``): a report reads only
the results store, so the rows record what it needs of the plugins (their layouts, the
reference detector). The history sits above the engine too and imports nothing of it: it reads
stored runs and never runs a model.

Two wings on one level do not import each other, in either direction. Decided from the code:
stats and stream share no import (stats reads stored rows, stream scores live pushes; both sit on
data/store and the contract), nor do data and store (they meet only in the engine), nor report
and analysis (two readers of engine output), nor engine and gate (the engine runs models and
never judges, the gate judges stored rows and never runs a model), nor app and testing (the
commands and the plugins' conformance kit); a level whose wings call each other would be one wing in all but
name. Every import counts, for the layering and for the cycles, also one inside a function or
under ``if TYPE_CHECKING:``.

Each offence is listed as ``file:line module -> module``.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

ROOT = next(p for p in Path(__file__).resolve().parents if (p / "pyproject.toml").is_file())
#: the package's folder: the built-in plugins are its subpackages detectors/ and protocols/
PACKAGE = ROOT / "slipbench"
PLUGIN_PACKAGES = ("slipbench.detectors", "slipbench.protocols")
CONTRACT = "contract"
#: what a plugin may import of the package
PLUGIN_API = (CONTRACT, "torch")
#: wing -> level; a wing may import wings of a lower level, its own wing and the contract
LEVELS = {
    CONTRACT: 0,
    "data": 1,
    "store": 1,
    "torch": 1,
    "stats": 2,
    "stream": 2,
    "engine": 3,
    "gate": 3,
    "history": 4,
    "report": 5,
    "analysis": 5,
    "app": 6,
    "testing": 6,
}
#: most .py files directly in slipbench/ (the contract and the package's __init__)
MAX_TOP_LEVEL = 10
#: plugin imports outside the contract, each with its reason; each is a debt to pay off
PLUGIN_EXCEPTIONS: dict[tuple[str, str], str] = {}  # (plugin module, target): why it may
#: wings a wing may not import although they lie below it, each with its reason
APART: dict[tuple[str, str], str] = {
    ("report", "engine"): "a report reads only the results store: protocol names, layouts, "
    "presentations and the reference detector are in the rows, never in the registry",
    ("history", "engine"): "a history reads stored runs (store.history) and judges them with "
    "the gate; it never plans or runs a model",
}


@dataclass(frozen=True)
class Import:
    source: str  # the importing module
    target: str  # the imported module of the package
    file: str  # the importing file, relative to the repository
    line: int
    runs: bool  # False under ``if TYPE_CHECKING:``

    def __str__(self) -> str:
        return f"{self.file}:{self.line} {self.source} -> {self.target}"


def modules() -> dict[str, Path]:
    """Every module of the package (plugins included) by dotted name."""
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join(("slipbench", *parts))] = path
    return found


def _type_checking_lines(tree: ast.AST) -> set[int]:
    lines = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for child in node.body:
                lines.update(range(child.lineno, child.end_lineno + 1))
    return lines


def imports(name: str, path: Path, known: set[str]) -> tuple[list[Import], list[Import]]:
    """The imports of package modules made by ``name`` (at any depth: module level, functions,
    ``TYPE_CHECKING`` blocks), and those of ``slipbench.*`` names that match no module."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    tree = ast.parse(path.read_text(), filename=str(path))
    typing_only = _type_checking_lines(tree)
    file = path.relative_to(ROOT).as_posix()
    found, unknown = [], []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                kept = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(kept + ([base] if base else []))
            # `from a import b`: b is a module of a or a name in a
            targets = [
                f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names
            ]
        else:
            continue
        for target in dict.fromkeys(targets):
            if not (target == "slipbench" or target.startswith("slipbench.")):
                continue
            owner = target
            while owner not in known and "." in owner:
                owner = owner.rpartition(".")[0]  # `import a.b.c` of a name: its module
            edge = Import(name, owner, file, node.lineno, node.lineno not in typing_only)
            if target not in known and owner == "slipbench" and target != "slipbench":
                unknown.append(Import(name, target, file, node.lineno, edge.runs))
            elif owner != name:
                found.append(edge)
    return found, unknown


def graph() -> tuple[dict[str, list[Import]], list[Import]]:
    mods = modules()
    known = set(mods)
    edges, unknown = {}, []
    for name, path in mods.items():
        edges[name], missing = imports(name, path, known)
        unknown += missing
    return edges, unknown


def wing(module: str) -> str | None:
    """The wing of a module of slipbench proper; None for the built-in plugins."""
    parts = module.split(".")
    if module.startswith(PLUGIN_PACKAGES):
        return None
    if len(parts) == 1:
        return CONTRACT  # slipbench/__init__.py
    if module == "slipbench.__main__":
        return "app"  # `python -m slipbench` is the command line
    return parts[1] if (ROOT / "slipbench" / parts[1]).is_dir() else CONTRACT


def _listing(offences) -> str:
    return "\n".join(f"  {o}" for o in sorted(offences, key=str))


def test_every_module_belongs_to_a_known_wing():
    strays = [m for m in modules() if wing(m) is not None and wing(m) not in LEVELS]
    assert not strays, (
        f"modules in no wing (add the wing to LEVELS and the docstring): {sorted(strays)}"
    )


def test_wings_import_only_downwards():
    edges, _ = graph()
    bad = []
    for found in edges.values():
        for imp in found:
            src, dst = wing(imp.source), wing(imp.target)
            if src is None:
                continue  # plugins: test_builtin_plugins_import_only_the_contract
            if dst is None:
                bad.append(imp)  # the package never imports a plugin: it reaches them by id
            elif src != dst and dst != CONTRACT and LEVELS[dst] >= LEVELS[src]:
                bad.append(imp)
    assert not bad, (
        "imports against the wing order (app, testing -> report, analysis -> history -> "
        "engine, gate -> stats, stream -> data, store, torch -> contract):\n" + _listing(bad)
    )


def test_wings_kept_apart_import_nothing_of_each_other():
    edges, _ = graph()
    bad = [
        imp
        for found in edges.values()
        for imp in found
        if (wing(imp.source), wing(imp.target)) in APART
    ]
    assert not bad, "imports between wings kept apart:\n" + "\n".join(
        f"  {imp}: {APART[wing(imp.source), wing(imp.target)]}" for imp in bad
    )


def test_imports_of_the_package_name_real_modules():
    _, unknown = graph()
    assert not unknown, "imports of slipbench names that no module defines:\n" + _listing(unknown)


def cycles(edges: dict[str, list[Import]]) -> list[list[Import]]:
    """The import cycles of a graph, each as its imports in turn. Every import counts, those
    under ``if TYPE_CHECKING:`` and inside functions too: a cycle kept out of import time by a
    deferred import is still two modules that cannot be read, tested or moved apart."""
    found: list[list[Import]] = []
    state: dict[str, int] = {}
    path: list[Import] = []

    def visit(node: str) -> None:
        state[node] = 1
        for imp in sorted(edges.get(node, []), key=lambda i: i.target):
            path.append(imp)
            if state.get(imp.target) == 1:
                start = next(k for k, i in enumerate(path) if i.source == imp.target)
                found.append(path[start:])
            elif imp.target not in state:
                visit(imp.target)
            path.pop()
        state[node] = 2

    for node in sorted(edges):
        if node not in state:
            visit(node)
    return found


def test_no_import_cycles():
    edges, _ = graph()
    found = cycles(edges)
    assert not found, "import cycles, each as its imports in turn:\n" + "\n--\n".join(
        "\n".join(f"  {i}" for i in cycle) for cycle in found
    )


def test_the_cycle_check_sees_deferred_imports():
    """A cycle closed by an import in a function and one under ``TYPE_CHECKING`` (the shape
    benchfile, calibrate and gateplan had) is found; a chain without a way back is not."""
    a, b, c = "slipbench.app.a", "slipbench.app.b", "slipbench.app.c"
    planted = {
        a: [Import(a, b, "a.py", 9, runs=True)],  # inside a function: runs when called
        b: [Import(b, a, "b.py", 3, runs=False)],  # under TYPE_CHECKING
        c: [Import(c, a, "c.py", 1, runs=True)],
    }
    assert [[(i.source, i.target) for i in cycle] for cycle in cycles(planted)] == [
        [(a, b), (b, a)]
    ]
    assert cycles({a: [Import(a, b, "a.py", 1, True)], b: [], c: []}) == []


def test_the_top_level_stays_small():
    top = sorted(p.name for p in (ROOT / "slipbench").glob("*.py"))
    assert len(top) <= MAX_TOP_LEVEL, (
        f"{len(top)} .py files directly in slipbench/ (at most {MAX_TOP_LEVEL}): {top}; "
        "a module with a job of its own belongs in a wing"
    )


def _own_helper(source: str, target: str) -> bool:
    """A plugin's own helpers: its folder's __init__ and the modules of its folder whose name
    starts with the plugin's first word (lstm, lstm_kernels and lstm_bench are one family)."""
    folder, stem = source.rsplit(".", 1)
    if target == folder:
        return True
    if target.rpartition(".")[0] != folder:
        return False
    return target.rpartition(".")[2].split("_")[0] == stem.split("_")[0]


def test_builtin_plugins_import_only_the_contract():
    edges, _ = graph()
    bad, excused = [], set()
    for name, found in edges.items():
        if not name.startswith(PLUGIN_PACKAGES):
            continue
        for imp in found:
            if wing(imp.target) in PLUGIN_API or _own_helper(name, imp.target):
                continue
            if (imp.source, imp.target) in PLUGIN_EXCEPTIONS:
                excused.add((imp.source, imp.target))
                continue
            bad.append(imp)
    assert not bad, (
        "built-in plugins importing beyond the contract and their own helpers:\n" + _listing(bad)
    )
    stale = set(PLUGIN_EXCEPTIONS) - excused
    assert not stale, f"exceptions no longer needed (remove them): {sorted(stale)}"


def test_the_graph_sees_imports():
    """The checks above would pass on an empty graph: make sure the parser finds real imports,
    of every kind (absolute, from-import of a module, relative, inside a function)."""
    edges, _ = graph()
    targets = {m: {i.target for i in found} for m, found in edges.items()}
    assert "slipbench.base" in targets["slipbench.engine.registry"]
    assert "slipbench.protocol" in targets["slipbench.protocols.window_size"]
    assert "slipbench.detectors.lstm_kernels" in targets["slipbench.detectors.lstm"]
    assert {wing(m) for m in edges} >= set(LEVELS) | {None}


# ----------------------------------------------------------------------------- a metric declared once
#: the results schema, where each figure is declared (name, kind, label, unit, display, worse,
#: rate, tolerance) and from which every list of figures is a query
SCHEMA = ROOT / "slipbench" / "store" / "columns.py"
#: the default figure of many signatures (``metric="accuracy"``): its spellings are not counted
DEFAULT_FIGURE = "accuracy"


def figure_names() -> set[str]:
    """The declared figures: the first argument of each ``Figure(...)`` in the schema."""
    calls = [n for n in ast.walk(ast.parse(SCHEMA.read_text())) if isinstance(n, ast.Call)]
    return {
        c.args[0].value
        for c in calls
        if isinstance(c.func, ast.Name)
        and c.func.id == "Figure"
        and c.args
        and isinstance(c.args[0], ast.Constant)
    }


def _named(node: ast.AST, names: set[str]) -> bool:
    return isinstance(node, ast.Constant) and node.value in names


def _literal(node: ast.AST) -> bool:
    try:
        ast.literal_eval(node)
    except ValueError:
        return False
    return True


def hand_lists(tree: ast.AST, names: set[str]) -> list[int]:
    """Lines of a tuple, list or set of two or more figure names, or of a dict that maps two or
    more of them to constants (a label, a scale, a sign): a list of figures kept by hand. A dict
    whose values are computed (the figures of a cell) is their computation, not a list."""
    lines = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
            if sum(_named(e, names) for e in node.elts) >= 2:
                lines.append(node.lineno)
        elif isinstance(node, ast.Dict):
            keyed = [
                v for k, v in zip(node.keys, node.values) if k is not None and _named(k, names)
            ]
            if len(keyed) >= 2 and all(_literal(v) for v in keyed):
                lines.append(node.lineno)
    return lines


def test_no_list_of_figures_but_the_results_schema():
    """Every list of figures in slipbench is a query of the results schema. The built-in plugins
    may name the figures their tables show: they reach the package through the contract alone,
    as a third-party plugin does, so they cannot query the schema."""
    names = figure_names()
    found = [
        f"{path.relative_to(ROOT)}:{line}"
        for module, path in modules().items()
        if wing(module) is not None and path != SCHEMA
        for line in hand_lists(ast.parse(path.read_text()), names)
    ]
    assert not found, (
        "lists of figure names kept by hand (query slipbench.store.columns instead):\n  "
        + "\n  ".join(found)
    )


def test_a_figure_is_spelled_in_two_package_files_at_most():
    """Its declaration and at most one more file (its computation, or a plugin naming it): a
    figure's name is otherwise read from the schema (``TN_RATE.name``, :func:`figures`)."""
    names = figure_names() - {DEFAULT_FIGURE}
    files: dict[str, set[str]] = {n: set() for n in names}
    for path in modules().values():
        for node in ast.walk(ast.parse(path.read_text())):
            if _named(node, names):
                files[node.value].add(str(path.relative_to(ROOT)))
    spread = {n: sorted(f) for n, f in files.items() if len(f) > 2}
    assert not spread, f"figure names spelled in more than two package files: {spread}"


def test_the_figure_checks_see_lists():
    """The two checks above would pass on a schema they cannot read: make sure they see the
    figures and the lists of them."""
    names = figure_names()
    assert {"tn_rate", "false_alarms_per_min", DEFAULT_FIGURE} <= names
    planted = ast.parse(
        'A = ("tp_rate", "tn_rate")\nB = {"tn_rate": 1, "auroc": -1}\n'
        'C = {"tn_rate": f(x), "auroc": g(x)}\nD = ["key", "tn_rate"]\n'
    )
    assert hand_lists(planted, names) == [1, 2]


# ----------------------------------------------------------------------------- a row declared once
#: how many role-bearing column names make a list of them kept by hand
ROLE_LIST = 3


def role_names() -> set[str]:
    """The columns the results schema gives a role other than a figure's (those have their own
    check above): the seed, the entrant's, the settings, the cell's."""
    from slipbench.store.columns import COLUMNS, FIGURE

    return {c.name for c in COLUMNS.values() if c.role and c.role != FIGURE}


def role_lists(tree: ast.AST, names: set[str]) -> list[int]:
    """Lines of a tuple, list or set naming :data:`ROLE_LIST` or more role-bearing columns: a
    list of identity or setting columns kept by hand."""
    return [
        node.lineno
        for node in ast.walk(tree)
        if isinstance(node, (ast.Tuple, ast.List, ast.Set))
        and sum(_named(e, names) for e in node.elts) >= ROLE_LIST
    ]


#: the hand lists left (none; 22 before the roles were the schema's, 9 before ``named``), per
#: file: a file may hold no more, and one that holds fewer lowers its count here
LEFT: dict[str, int] = {}


def test_no_list_of_role_columns_but_the_results_schema():
    """Every list of identity or setting columns in slipbench is a query of the results schema
    (:func:`slipbench.store.columns.identity`): a new role-bearing column is one entry there,
    and every pairing, series and table keeps it apart. The lists of :data:`LEFT` may stay, no
    more of them."""
    names = role_names()
    found: dict[str, list[int]] = {}
    for module, path in modules().items():
        lines = role_lists(ast.parse(path.read_text()), names)
        if wing(module) is not None and path != SCHEMA and lines:
            found[str(path.relative_to(ROOT))] = sorted(lines)
    counts = {f: len(lines) for f, lines in found.items()}
    more = {f: found[f] for f, n in counts.items() if n > LEFT.get(f, 0)}
    assert not more, (
        "lists of role-bearing columns kept by hand (query slipbench.store.columns.identity "
        f"instead): {more}"
    )
    assert counts == LEFT, f"fewer hand lists than LEFT says: lower it to {counts}"


def test_the_role_check_sees_lists():
    """The check above would pass on a schema without roles: make sure it sees them and the
    lists of them."""
    names = role_names()
    assert {"seed", "detector", "input", "split", "cell", "train_sensors", "sensor_map"} <= names
    assert not names & {"sensor_type", "accuracy", "status"}
    planted = ast.parse(
        'A = ("protocol", "split", "labels")\nB = ["seed", "cell", "status"]\n'
        'C = {"detector", "input", "normalize", "x"}\nD = (*POOL, "cell")\n'
    )
    assert role_lists(planted, names) == [1, 3]
