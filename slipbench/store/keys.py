"""Cache keys that cannot go stale: canonical JSON of plain values, and the identity of code.

A cell's key is the hash of everything that determines its result. Two things make such keys
go stale silently, and this module closes both:

- *Representations that drift.* A key built from ``repr`` or ``json.dumps(default=str)`` holds
  ``np.float64(25.0)``, which another NumPy prints differently, while ``25`` and ``25.0`` (the
  same speed) give two keys. :func:`canonical` accepts plain JSON values only, turns NumPy
  scalars and arrays, tuples and dataclasses into them, writes every number one way, and
  refuses anything else with a TypeError naming the value.
- *Code that changes under a fixed version string.* :func:`code_identity` hashes the source
  files that run, so editing slipbench or a plugin changes the keys of what they compute.
"""

from __future__ import annotations

import ast
import dataclasses
import hashlib
import importlib.machinery
import importlib.util
import json
import math
import sys
import types
import uuid
from functools import cache
from importlib.metadata import packages_distributions, version
from pathlib import Path
from typing import Any

import numpy as np

from slipbench.store.reads import plugin_files

#: Version of the key layout; bumping it changes every key (do so when the meaning of a field
#: changes without its value changing).
KEY_SCHEMA = 1


def canonical(value: Any, where: str = "key") -> Any:
    """``value`` as plain JSON data with one spelling per meaning.

    - ``bool``, ``str`` (and ``np.str_``), ``None`` stay as they are; ``np.bool_`` becomes bool;
    - integers (Python or NumPy) become ``int``; a finite float that is a whole number becomes
      that ``int`` (``25.0`` and ``25`` mean the same speed), any other finite float stays a
      ``float`` and is written by JSON as the shortest repr that round-trips; NaN and
      infinities become ``{"__float__": "nan" | "inf" | "-inf"}``;
    - tuples, lists and NumPy arrays become lists; dataclass instances become dicts of their
      fields; dicts must have string keys.

    Anything else (a set, a path, a pandas object, an arbitrary object) raises TypeError naming
    the value and where it sits, rather than entering a key as a representation that can drift.
    """
    if value is None or isinstance(value, (bool, str)):
        return str(value) if isinstance(value, str) else value
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return _float(float(value))
    if isinstance(value, (list, tuple)):
        return [canonical(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "biuf":
            raise TypeError(
                f"{where}: a NumPy array of dtype {value.dtype} cannot be part of a cache key"
            )
        return canonical(value.tolist(), where)
    if isinstance(value, dict):
        out = {}
        for k, v in value.items():
            if not isinstance(k, str):
                raise TypeError(
                    f"{where}: dict key {k!r} is a {type(k).__name__}, not a str; cache keys take string keys only"
                )
            # plain values at once: every read digests each result row's ~100 values, and the
            # recursion (its `where` text) took 2.5x as long (benchmarks/results/store.txt)
            kind = type(v)
            out[str(k)] = (
                v
                if kind in _PLAIN
                else _float(v)
                if kind is float
                else canonical(v, f"{where}.{k}")
            )
        return out
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {
            f.name: canonical(getattr(value, f.name), f"{where}.{f.name}")
            for f in dataclasses.fields(value)
        }
    raise TypeError(
        f"{where}: {value!r} (a {type(value).__module__}.{type(value).__qualname__}) cannot be part of a "
        "cache key; pass plain numbers, strings, booleans, None, lists, tuples, dicts or dataclasses"
    )


_PLAIN = frozenset({str, int, bool, type(None)})  # exactly these types are their own canonical form


def _float(x: float) -> Any:
    """A float's canonical form: the int it equals, itself, or NaN and infinities spelt out."""
    if not math.isfinite(x):
        return {"__float__": "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf")}
    return int(x) if x.is_integer() else x


def canonical_json(fields: dict[str, Any]) -> str:
    """The exact text that :func:`cell_key` hashes: ``{"fields": ..., "schema": KEY_SCHEMA}``,
    sorted keys, no spaces, UTF-8 kept as is."""
    return json.dumps(
        {"schema": KEY_SCHEMA, "fields": canonical(fields)},
        sort_keys=True,
        separators=(",", ":"),
        ensure_ascii=False,
        allow_nan=False,
    )


def cell_key(fields: dict[str, Any]) -> str:
    """A 20-hex-digit (80-bit) SHA-256 content address of a cell's description.

    ``fields`` must hold plain values (see :func:`canonical`); equal meanings give equal keys
    whatever the NumPy version or the int/float spelling of a number.
    """
    return hashlib.sha256(canonical_json(fields).encode()).hexdigest()[:20]


# ----------------------------------------------------------------------------- code identity
# A module whose source cannot be read (a REPL, a notebook) gets an identity that is new in every
# process: its cells are never taken from another process's cache, which is slower but never wrong.
_PROCESS_NONCE = f"process:{uuid.uuid4().hex}"
_CODE_SUFFIXES = (".py", *importlib.machinery.EXTENSION_SUFFIXES)


def code_identity(obj: type | types.ModuleType) -> str:
    """An identity of the code that runs ``obj`` (a class or a module), for cache keys.

    The unit hashed is the top-level regular package that holds ``obj``: every ``.py`` file and
    compiled extension under it, with their paths relative to it, so the same code installed
    elsewhere has the same identity. For slipbench itself the unit is the whole engine,
    including the packages of its built-in detectors and protocols. A module that is in no
    package (a plugin file of a ``--plugins`` folder, a script) is hashed with the modules and
    packages beside it that it imports, followed through their own imports (see
    :func:`local_files`). A class's declared ``data_files`` (paths relative to the folder of the
    module that declares them; a folder stands for every file under it) are hashed too, and so
    are the files under the unit's folder that importing it read (:func:`note_import`).
    Returns

    - ``"src:<32 hex>"``: a SHA-256 of those files;
    - ``"dist:<name>==<version>"``: where no source file is readable (a zip or frozen import),
      the version of the distribution that installed it;
    - ``"process:<32 hex>"``: where neither exists (a class typed into a REPL or notebook),
      an identity unique to this process.

    Library versions (NumPy, torch) are deliberately not part of it: rows record them, and an
    upgrade does not silently throw away every cached cell. The result is cached per process
    (the first call for slipbench reads its ~30 source files once).
    """
    name = obj.__name__ if isinstance(obj, types.ModuleType) else getattr(obj, "__module__", None)
    if not isinstance(name, str) or not (isinstance(obj, (type, types.ModuleType))):
        raise TypeError(f"code_identity takes a class or a module, got {obj!r}")
    unit = _unit(name)
    code = _unit_identity(unit)
    data = data_files(obj) if isinstance(obj, type) else []
    extra = tuple((label, str(path)) for label, path in data) + _READ_AT_IMPORT.get(unit, ())
    return _with_data(code, extra) if extra else code


#: unit -> (label, path) of the files under its folder that importing it read and that it
#: does not hash as code (a helper loaded by path, a table read at import): part of its identity
_READ_AT_IMPORT: dict[str, tuple[tuple[str, str], ...]] = {}


def note_import(module: str, opened: set[str]) -> list[Path]:
    """Make the files read while importing ``module`` (``opened``, from
    :func:`slipbench.store.reads.reading`) that lie under its unit's folder part of its code
    identity; return the others it read that no identity holds (outside its folder, not code of
    slipbench), for a warning."""
    unit = _unit(module)
    home = _home(unit)
    inside: list[Path] = []
    outside: list[Path] = []
    for path in unkeyed(unit, opened):
        (inside if home is not None and path.is_relative_to(home) else outside).append(path)
    if inside and home is not None:
        labels = (f"read:{p.relative_to(home).as_posix()}" for p in inside)
        _READ_AT_IMPORT[unit] = tuple(sorted(zip(labels, map(str, inside), strict=True)))
    return outside


def unkeyed(cls_or_unit: type | str, opened: set[str]) -> list[Path]:
    """The files among ``opened`` that the code identity of a plugin class (or of a unit)
    does not hash: not its code, declared data or files read at import, not slipbench's code,
    not Python's or an installed library's (:func:`slipbench.store.reads.plugin_files`)."""
    candidates = plugin_files(opened)
    if not candidates:
        return []  # the common case costs no hashing of file lists
    if isinstance(cls_or_unit, type):
        unit = _unit(cls_or_unit.__module__)
        declared = {p.resolve() for _, p in data_files(cls_or_unit)}
    else:
        unit, declared = cls_or_unit, set()
    known = declared | _covered(unit) | _covered("slipbench")
    known |= {Path(p) for _, p in _READ_AT_IMPORT.get(unit, ())}
    engine = _home("slipbench")  # slipbench's own files (cards, tables) are slipbench's identity
    return [p for p in candidates if p not in known and not (engine and p.is_relative_to(engine))]


def file_digest(path: Path) -> str:
    """A 16-hex-digit SHA-256 of a file's bytes ("missing" where it cannot be read)."""
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()[:16]
    except OSError:
        return "missing"


def changed_reads(row: dict[str, Any]) -> list[str]:
    """The files of a stored row's ``unkeyed_reads`` whose content is no longer what it was."""
    recorded = json.loads(row.get("unkeyed_reads") or "{}")
    return [path for path, digest in recorded.items() if file_digest(Path(path)) != digest]


@cache
def _covered(unit: str) -> frozenset[Path]:
    return frozenset(p.resolve() for _, p in _source_files(unit))


def _home(unit: str) -> Path | None:
    """The folder that holds a unit: its package folder, or the folder of a plain module."""
    folders, single = _locations(unit)
    if single is not None:
        return single.resolve().parent
    return folders[0].resolve() if folders else None


def data_files(cls: type) -> list[tuple[str, Path]]:
    """(label, path) of every file a class declares in ``data_files``: each entry relative to
    the folder of the module of the class (in its MRO) that declares the attribute; a folder
    entry gives every file under it (hidden ones and ``__pycache__`` aside). A declared path
    that does not exist is listed as it is (its absence is part of the identity); the registry
    refuses such a plugin when it loads it (:func:`missing_data_files`)."""
    owner = next((c for c in cls.__mro__ if "data_files" in vars(c)), None)
    declared = getattr(cls, "data_files", ())
    if owner is None or not declared:
        return []
    file = getattr(sys.modules.get(owner.__module__), "__file__", None)
    if not file:
        return []
    home = Path(file).parent
    out: list[tuple[str, Path]] = []
    for entry in declared:
        path = home / entry
        if path.is_dir():
            out += [(f"{entry}/{label}", p) for label, p in _files_under(path, None)]
        else:
            out.append((str(entry), path))
    return out


def missing_data_files(cls: type) -> list[str]:
    """The declared ``data_files`` of a class that are not there (or not relative paths)."""
    declared = getattr(cls, "data_files", ())
    if isinstance(declared, str) or not isinstance(declared, (tuple, list)):
        return [f"data_files must be a tuple of paths, got {declared!r}"]
    bad = [str(e) for e in declared if not isinstance(e, str) or Path(e).is_absolute()]
    if bad:
        return [f"{e} (data_files are paths relative to the plugin's module)" for e in bad]
    return [label for label, path in data_files(cls) if not path.exists()]


@cache
def _with_data(code: str, files: tuple[tuple[str, str], ...]) -> str:
    digest = hashlib.sha256(code.encode())
    for label, path in sorted(files):
        try:
            data = Path(path).read_bytes()
        except OSError:
            digest.update(f"{label}\0missing\0".encode())
            continue
        digest.update(f"{label}\0{len(data)}\0".encode())
        digest.update(data)
    return f"src:{digest.hexdigest()[:32]}"


def _unit(module: str) -> str:
    """The outermost regular (non-namespace) package or module that holds ``module``."""
    parts = module.split(".")
    for i in range(1, len(parts) + 1):
        prefix = ".".join(parts[:i])
        found = sys.modules.get(prefix)
        if found is not None and getattr(found, "__file__", None):
            return prefix
        if found is None and i < len(parts):
            spec = importlib.util.find_spec(prefix)
            if spec is not None and spec.origin not in (None, "namespace"):
                return prefix
    return module


@cache
def _unit_identity(unit: str) -> str:
    files = _source_files(unit)
    if files:
        digest = hashlib.sha256()
        for label, path in sorted(files):
            try:
                data = path.read_bytes()
            except OSError:
                continue  # vanished or unreadable: the files that remain still identify the code
            digest.update(f"{label}\0{len(data)}\0".encode())
            digest.update(data)
        return f"src:{digest.hexdigest()[:32]}"
    dists = packages_distributions().get(unit.split(".")[0], [])
    if dists:
        return "dist:" + ",".join(f"{d}=={version(d)}" for d in sorted(set(dists)))
    return _PROCESS_NONCE


def _source_files(unit: str) -> list[tuple[str, Path]]:
    """(label, path) of every code file of ``unit``. A label is the file's package, dotted, and
    its name (``slipbench.detectors/holweg.py``), the same wherever and however (wheel or
    editable) the package is installed."""
    files: dict[str, Path] = {}
    for package in _engine_packages() if unit == "slipbench" else [unit]:
        folders, single = _locations(package)
        if single is not None:
            return local_files(single, unit)
        for root in folders:
            for label, path in _files_under(root, _CODE_SUFFIXES):
                folder, _, name = label.rpartition("/")
                dotted = ".".join([package, *folder.split("/")]) if folder else package
                files.setdefault(f"{dotted}/{name}", path)
    return list(files.items())


def _files_under(root: Path, suffixes: tuple[str, ...] | None) -> list[tuple[str, Path]]:
    """(path relative to ``root``, path) of the files under ``root`` (those ending in one of
    ``suffixes``, or all), outside hidden folders and ``__pycache__``."""
    out = []
    for path in sorted(root.rglob("*")):
        relative = path.relative_to(root)
        if (
            (suffixes is None or path.name.endswith(suffixes))
            and path.is_file()
            and not any(p.startswith(".") or p == "__pycache__" for p in relative.parts[:-1])
        ):
            out.append((relative.as_posix(), path))
    return out


def local_files(file: Path, unit: str = "") -> list[tuple[str, Path]]:
    """(label, path) of a module that is in no package and of the code beside it that it runs:
    the modules (``helper.py``) and packages (``sub/``, every code file under it) of its
    folder that it imports, found by reading the import statements of each file taken
    (``import helper``, ``from sub.mod import f``, inside functions too), so the closure is
    the same in every process whatever has been imported so far. A name counts where it is
    (or, not yet imported, would be) loaded from inside the folder and no other installed
    distribution provides it; the standard library and slipbench never do. Labels are paths
    relative to the folder, so the same files elsewhere hash alike. A module loaded in another
    way (``importlib`` by path, ``exec``) is not seen here; the registry adds the files read
    while importing a plugin (:func:`note_import`)."""
    root = file.parent
    own = set(_distributions().get(unit, []))
    taken: dict[str, Path] = {file.name: file}
    queue = [file]
    while queue:
        current = queue.pop()
        for name in sorted(_imported_names(current)):
            found = _local_module(name, root, own)
            if found is None:
                continue
            where = found.resolve().relative_to(root.resolve()).as_posix()
            if found.is_dir():
                more = [(f"{where}/{label}", p) for label, p in _files_under(found, _CODE_SUFFIXES)]
            else:
                more = [(where, found)]
            for label, path in more:
                if label not in taken:
                    taken[label] = path
                    if path.suffix == ".py":
                        queue.append(path)
    return sorted(taken.items())


def _imported_names(path: Path) -> set[str]:
    """The top-level names a Python file imports absolutely (relative imports stay in their
    package, which is hashed whole)."""
    try:
        tree = ast.parse(path.read_bytes())
    except (OSError, SyntaxError, ValueError):
        return set()  # its bytes are still hashed; a file that does not parse imports nothing
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


def _local_module(name: str, root: Path, own: set[str]) -> Path | None:
    """The file or package folder inside ``root`` that ``import name`` loads, or None."""
    if name in sys.stdlib_module_names or name in ("slipbench", "__main__"):
        return None
    if set(_distributions().get(name, [])) - own:
        return None  # an installed library (numpy, torch), not the plugin's own code
    loaded = sys.modules.get(name)
    if loaded is not None:
        paths = getattr(loaded, "__path__", None)
        file = getattr(loaded, "__file__", None)
        where = Path(list(paths)[0]) if paths else Path(file) if file else None
        if where is not None and where.name == "__init__.py":
            where = where.parent
    else:
        candidates = [root / name, root / f"{name}.py"] + [
            root / f"{name}{suffix}" for suffix in importlib.machinery.EXTENSION_SUFFIXES
        ]
        where = next((c for c in candidates if c.exists()), None)
    if where is None or not where.exists():
        return None
    try:
        where.resolve().relative_to(root.resolve())
    except ValueError:
        return None  # loaded from elsewhere on sys.path
    return where


@cache
def _distributions() -> dict[str, list[str]]:
    return dict(packages_distributions())


def _locations(package: str) -> tuple[list[Path], Path | None]:
    """The folders of a package, or the file of a plain module (a script run as ``__main__``
    has a file but no spec)."""
    module = sys.modules.get(package)
    if module is not None and getattr(module, "__path__", None) is not None:
        return [Path(p) for p in module.__path__], None
    if module is not None:
        file = getattr(module, "__file__", None)
        return [], Path(file) if file and Path(file).is_file() else None
    spec = importlib.util.find_spec(package)
    if spec is None:
        return [], None
    if spec.submodule_search_locations is not None:
        return [Path(p) for p in spec.submodule_search_locations], None
    return [], Path(spec.origin) if spec.origin and Path(spec.origin).is_file() else None


def _engine_packages() -> list[str]:
    """slipbench and the packages of its built-in plugins (the registries name them); the
    plugins' folders lie inside ``slipbench/``, so their files are labelled alike either way."""
    return ["slipbench", "slipbench.detectors", "slipbench.protocols"]


def own_code_identity(cls: type) -> str:
    """The identity of a plugin class's own code, narrower than :func:`code_identity`: the
    module that defines it and the slipbench modules it imports, followed through their own
    slipbench imports (for a built-in detector, its file and the contract it uses: ``base``,
    ``spectra``, ``params``, ...), and, for a class outside slipbench, its
    :func:`code_identity` too. A change elsewhere in slipbench (a report, a command) leaves it
    as it is. What it is for: measurements of a detector's behaviour that stay true while its
    code does (a bench's seed variance), not cache keys, which must change with any code that
    runs."""
    module = sys.modules.get(cls.__module__)
    file = getattr(module, "__file__", None)
    if not file:
        return code_identity(cls)  # no source to follow (a REPL class): the strict identity
    digest = hashlib.sha256()
    if _unit(cls.__module__) != "slipbench":
        digest.update(code_identity(cls).encode())
    for label, path in _slipbench_closure(Path(file).resolve()):
        digest.update(f"{label}\0".encode())
        digest.update(path.read_bytes())
    for label, path in data_files(cls):
        digest.update(f"data:{label}\0{file_digest(path)}\0".encode())
    return f"src:{digest.hexdigest()[:32]}"


@cache
def _slipbench_closure(start: Path) -> tuple[tuple[str, Path], ...]:
    """(label, path) of ``start`` and of the slipbench modules it imports, transitively (import
    statements read, inside functions too, so the closure does not depend on what has been
    imported so far); labels are dotted module names, the same wherever slipbench is
    installed."""
    taken: dict[str, Path] = {"": start}
    queue = [start]
    while queue:
        tree = _parsed(queue.pop())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
            else:
                continue
            for name in names:
                path = _slipbench_module(name)
                if path is not None and name not in taken:
                    taken[name] = path
                    queue.append(path)
    return tuple(sorted(taken.items()))


def _parsed(path: Path) -> ast.AST:
    try:
        return ast.parse(path.read_bytes())
    except (OSError, SyntaxError, ValueError):
        return ast.Module(body=[], type_ignores=[])  # its bytes are still hashed


def _slipbench_module(name: str) -> Path | None:
    """The source file of a slipbench module (not a package's ``__init__``, nor a name that is
    an attribute rather than a module)."""
    if name.split(".")[0] != "slipbench" or "." not in name:
        return None
    try:
        spec = importlib.util.find_spec(name)
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.origin or spec.submodule_search_locations is not None:
        return None
    path = Path(spec.origin)
    return path.resolve() if path.suffix == ".py" and path.is_file() else None
