"""What ``slipbench list`` shows of an entry-point plugin, read from its source, not imported.

Importing every plugin to list it cost 4x an import of pandas and 272 MiB (the detectors import
scipy.signal, scikit-learn and numba). A plugin declares what ``list`` shows in its class body:
its docstring, ``inputs``, ``reference``, ``requires``, ``install_hint``,
``_parameter_constraints`` and the keyword defaults of ``__init__``. :func:`declaration` parses
the plugin's module (and the modules its base classes and constants come from) with :mod:`ast`
and evaluates those expressions where they are plain: literals, names bound to them, and calls
of :mod:`slipbench.params`' constraint classes. Anything else (a computed default, a decorator,
a base class from outside, a module-level import that is not installed) raises
:class:`NeedsImport`, and the registry imports that one plugin instead, as before.
"""

from __future__ import annotations

import ast
import builtins
import functools
import importlib.util
import operator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

_BUILTINS = {"int": int, "float": float, "str": str, "bool": bool, "tuple": tuple}
_ARITHMETIC = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.LShift: operator.lshift,
}
_SHOWN = ("inputs", "reference", "requires", "install_hint", "_parameter_constraints")


class NeedsImport(Exception):
    """The plugin's declaration cannot be read without running its code (the message says why)."""


@dataclass
class _Module:
    name: str
    imports: dict[str, tuple[str, str | None]] = field(
        default_factory=dict
    )  # name -> (module, attr)
    assigns: dict[str, ast.expr] = field(default_factory=dict)
    classes: dict[str, ast.ClassDef] = field(default_factory=dict)
    absolute: list[str] = field(default_factory=list)  # top-level modules it imports


def _source(name: str) -> tuple[Path, bool]:
    """A module's source file and whether it is a package, found without importing its parent
    packages (find_spec would: slipbench.torch's __init__ imports numpy)."""
    top, *rest = name.split(".")
    try:
        spec = importlib.util.find_spec(top)
    except (ImportError, ValueError) as exc:
        raise NeedsImport(f"module {name} not found: {exc}") from None
    if spec is None or not spec.origin or not spec.origin.endswith(".py"):
        raise NeedsImport(f"module {name} has no Python source")
    path, package = Path(spec.origin), bool(spec.submodule_search_locations)
    for part in rest:
        if not package:
            raise NeedsImport(f"{name}: {path} is not a package")
        inner = path.parent / part / "__init__.py"
        path, package = (inner, True) if inner.is_file() else (path.parent / f"{part}.py", False)
        if not path.is_file():
            raise NeedsImport(f"module {name} has no source file at {path}")
    return path, package


@functools.cache
def _module(name: str) -> _Module:
    path, is_package = _source(name)
    tree = ast.parse(path.read_bytes(), str(path))
    package = name if is_package else name.rpartition(".")[0]
    out = _Module(name)
    for node in tree.body:
        if isinstance(node, ast.Import):
            for a in node.names:
                out.imports[a.asname or a.name.split(".")[0]] = (a.name, None)
                out.absolute.append(a.name)
        elif isinstance(node, ast.ImportFrom):
            base = _absolute(node, package)
            if node.level == 0 and base != "__future__":
                out.absolute.append(base)
            for a in node.names:
                out.imports[a.asname or a.name] = (base, a.name)
        elif isinstance(node, ast.ClassDef):
            out.classes[node.name] = node
        else:
            for target, value in _assignments(node):
                out.assigns[target] = value
    return out


def _absolute(node: ast.ImportFrom, package: str) -> str:
    if node.level == 0:
        return node.module or ""
    parts = package.split(".")
    base = ".".join(parts[: len(parts) - node.level + 1])
    return f"{base}.{node.module}" if node.module else base


def _assignments(node: ast.stmt) -> list[tuple[str, ast.expr]]:
    if isinstance(node, ast.Assign) and len(node.targets) == 1:
        target = node.targets[0]
        if isinstance(target, ast.Name):
            return [(target.id, node.value)]
    if isinstance(node, ast.AnnAssign) and node.value is not None:
        if isinstance(node.target, ast.Name):
            return [(node.target.id, node.value)]
    return []


def _name(module: _Module, name: str, seen: frozenset[tuple[str, str]] = frozenset()) -> Any:
    """The value a module-level ``name`` is bound to: a literal assignment, a constraint class of
    slipbench.params, or the same in the module it is imported from."""
    if (module.name, name) in seen:
        raise NeedsImport(f"{name} in {module.name} refers to itself")
    seen = seen | {(module.name, name)}
    if name in module.assigns:
        return _value(module, module.assigns[name], seen)
    if name in module.imports:
        source, attribute = module.imports[name]
        if attribute is None:
            raise NeedsImport(f"{name} is a module")
        if source == "slipbench.params":  # the constraint classes, imported for real (cheap)
            import slipbench.params

            found = getattr(slipbench.params, attribute, None)
            if isinstance(found, type):
                return found
        return _name(_module(source), attribute, seen)
    if name in _BUILTINS:
        return _BUILTINS[name]
    raise NeedsImport(f"{name} in {module.name} is not a plain value")


def _value(module: _Module, node: ast.expr, seen: frozenset[tuple[str, str]] = frozenset()) -> Any:
    """A plain expression's value (see the module's docstring); NeedsImport for the rest."""
    if isinstance(node, ast.Constant):
        return node.value
    if isinstance(node, (ast.Tuple, ast.List)):
        items = [_value(module, e, seen) for e in node.elts]
        return tuple(items) if isinstance(node, ast.Tuple) else items
    if isinstance(node, ast.Dict) and None not in node.keys:
        return {
            _value(module, k, seen): _value(module, v, seen)
            for k, v in zip(node.keys, node.values)
            if k is not None
        }
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        operand = _value(module, node.operand, seen)
        if isinstance(operand, (int, float)):
            return -operand
    if isinstance(node, ast.BinOp) and type(node.op) in _ARITHMETIC:
        left, right = _value(module, node.left, seen), _value(module, node.right, seen)
        if isinstance(left, (int, float)) and isinstance(right, (int, float)):
            return _ARITHMETIC[type(node.op)](left, right)
    if isinstance(node, ast.Name):
        return _name(module, node.id, seen)
    if isinstance(node, ast.Call):
        func = _value(module, node.func, seen)
        if isinstance(func, type) and func.__module__ == "slipbench.params":
            args = [_value(module, a, seen) for a in node.args]
            kwargs = {k.arg: _value(module, k.value, seen) for k in node.keywords if k.arg}
            if len(kwargs) == len(node.keywords):
                return func(*args, **kwargs)
    raise NeedsImport(f"{ast.unparse(node)} in {module.name} is not a plain value")


@dataclass
class _Class:
    attributes: dict[str, Any]
    parameters: dict[str, Any] | None  # None: no __init__ of its own or inherited
    ancestors: set[tuple[str, str]]  # (module, class) of itself and every base
    body: dict[str, tuple[_Module, ast.expr]] = field(default_factory=dict)  # class-level names


def _constraints(module: _Module, node: ast.expr, scope: _Class) -> dict[str, str]:
    """``_parameter_constraints`` as name -> its text: a dict (``**`` merges included), a name
    bound to one in the class body or the module, or ``SomeClass.NAME``. A constraint that is
    not plain (it calls a library) is shown as declared, in its source's words."""
    if isinstance(node, ast.Dict):
        out: dict[str, str] = {}
        for key, value in zip(node.keys, node.values):
            if key is None:
                out.update(_constraints(module, value, scope))
            else:
                out[str(_value(module, key))] = _text(module, value)
        return out
    if isinstance(node, ast.Name) and node.id in scope.body:
        return _constraints(*scope.body[node.id], scope)
    if isinstance(node, ast.Name) and node.id in module.assigns:
        return _constraints(module, module.assigns[node.id], scope)
    if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
        owner = _class(module.name, node.value.id)
        if node.attr in owner.body:
            return _constraints(*owner.body[node.attr], owner)
    raise NeedsImport(f"{ast.unparse(node)} in {module.name} is not a plain dict of constraints")


def _text(module: _Module, node: ast.expr) -> str:
    try:
        return str(_value(module, node))
    except NeedsImport:
        return f"as declared: {ast.unparse(node)}"


def _class(module_name: str, class_name: str) -> _Class:
    module = _module(module_name)
    if class_name not in module.classes:
        if class_name in module.imports and module.imports[class_name][1]:
            source, attribute = module.imports[class_name]
            return _class(source, attribute or "")
        raise NeedsImport(f"no class {class_name} in {module_name}'s source")
    node = module.classes[class_name]
    if node.decorator_list or node.keywords:
        raise NeedsImport(f"class {class_name} is decorated or has a metaclass")
    merged = _Class({}, None, {(module_name, class_name)})
    for base in node.bases:
        if not isinstance(base, ast.Name):
            raise NeedsImport(f"a base of {class_name} is {ast.unparse(base)}")
        parent = _class(module_name, base.id)
        merged.attributes.update(parent.attributes)
        merged.parameters = parent.parameters if merged.parameters is None else merged.parameters
        merged.ancestors |= parent.ancestors
        merged.body.update(parent.body)
    for stmt in node.body:
        for target, value in _assignments(stmt):
            merged.body[target] = (module, value)
    for stmt in node.body:
        for target, value in _assignments(stmt):
            if target == "_parameter_constraints":
                merged.attributes[target] = _constraints(module, value, merged)
            elif target in _SHOWN:
                merged.attributes[target] = _value(module, value)
        if isinstance(stmt, ast.FunctionDef) and stmt.name == "__init__":
            merged.parameters = _defaults(module, stmt)
    return merged


def _defaults(module: _Module, init: ast.FunctionDef) -> dict[str, Any]:
    """Keyword parameters of ``__init__`` and their defaults (None where there is none)."""
    args = init.args
    positional = [*args.posonlyargs, *args.args][1:]  # self
    defaults: list[ast.expr | None] = [None] * (len(positional) - len(args.defaults))
    pairs = list(zip(positional, defaults + list(args.defaults)))
    pairs += list(zip(args.kwonlyargs, args.kw_defaults))
    return {
        a.arg: None if d is None else _value(module, d) for a, d in sorted(pairs, key=_arg_name)
    }


def _arg_name(pair: tuple[ast.arg, Any]) -> str:
    return pair[0].arg


def declaration(target: str, base: tuple[str, str]) -> dict[str, Any]:
    """What ``list`` shows of the plugin at entry point ``target`` ("module:Class"), a subclass
    of ``base`` (module, class): ``description`` (its docstring), ``attributes`` (those of
    _SHOWN it or a base declares) and ``parameters`` (name -> default). NeedsImport where that
    cannot be read without running its code, or its module imports a package not installed
    (its import would fail: the registry reports how)."""
    module_name, _, class_name = target.partition(":")
    if not class_name or "." in class_name:
        raise NeedsImport(f"entry point {target} does not name a class of its module")
    module = _module(module_name)
    for imported in module.absolute:
        top = imported.split(".")[0]
        if top not in builtins.__dict__ and importlib.util.find_spec(top) is None:
            raise NeedsImport(f"{module_name} imports {imported}, which is not installed")
    if class_name not in module.classes:
        raise NeedsImport(f"{class_name} is not defined in {module_name} itself")
    found = _class(module_name, class_name)
    if base not in found.ancestors:
        raise NeedsImport(f"{class_name}'s source does not show it a subclass of {base[1]}")
    node = module.classes[class_name]
    return {
        "description": ast.get_docstring(node) or "",
        "attributes": found.attributes,
        "parameters": found.parameters or {},
    }
