"""Detectors and protocols by id: entry points (built-ins included) and plugin folders.

Every plugin, built-in or third-party, is found the same way: an entry point in the group
``slipbench.detectors`` or ``slipbench.protocols`` (slipbench's own are declared in its
``pyproject.toml``), or a file of a plugin folder. The entry-point or file name is the plugin's
id, its one name: the registry writes it on the class as ``name``. A plugin is imported only
when it is selected, so one that fails to import is reported then, with its id and the error,
and never breaks start-up or the other plugins.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import importlib.util
import inspect
import re
import sys
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path
from typing import TYPE_CHECKING, Any, Generic, TypeVar

from slipbench.errors import PluginError, UsageError, did_you_mean

if TYPE_CHECKING:
    from slipbench.base import BaseDetector
    from slipbench.protocol import BaseProtocol

# Ids are listed and checked from entry points and folder listings alone: the contract (numpy,
# pandas, pyarrow) is imported when a plugin is loaded, so a mistyped id is refused at once.


@dataclass(frozen=True)
class Source:
    origin: str  # where the id came from, for messages
    target: str  # "module:attribute" (entry point) or the module name of a plugin file
    load: Callable[[], Any]  # () -> module or class
    package: str = ""  # the distribution and version that installed it ("" for a plugin file)


#: module name -> file of every plugin file imported in this process; worker processes import
#: them again under the same names, so the classes they define unpickle there
PLUGIN_FILES: dict[str, str] = {}


def import_plugin_file(path: str | Path) -> object:
    """The module of a plugin file, imported once per process under a name made from its path
    (two plugin files with one stem stay apart in ``sys.modules``). Its folder goes to the end
    of ``sys.path``, so it may import the modules and packages beside it (``import helper``);
    installed packages keep precedence over them."""
    path = Path(path)
    digest = hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:10]
    module_name = f"slipbench_plugin_{path.stem}_{digest}"
    if module_name in sys.modules:
        return sys.modules[module_name]
    folder = str(path.resolve().parent)
    if folder not in sys.path:
        sys.path.append(folder)
    spec = importlib.util.spec_from_file_location(module_name, path)
    assert spec is not None and spec.loader is not None  # a .py file has a source loader
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[module_name]
        raise
    PLUGIN_FILES[module_name] = str(path)
    return module


def _note_reads(cls: type, opened: set[str], who: str) -> None:
    """Files read while importing a plugin: those under its folder join its code identity;
    any other (not slipbench's or a library's) is named in a warning, since no key sees it.
    Built-ins belong to slipbench, whose identity is its code alone."""
    if cls.__module__.split(".")[0] == "slipbench":
        return
    from slipbench.store.keys import note_import

    for path in note_import(cls.__module__, opened):
        warnings.warn(
            f"{who} read {path} while importing; it is outside the plugin's folder and not "
            "part of its code identity: cached cells do not see a change to it",
            stacklevel=2,
        )


def is_plugin_file(path: Path) -> bool:
    """Whether a ``*.py`` file of a plugin folder is a plugin: not a helper (``_name.py``) and
    not pytest's (``test_*.py``, ``*_test.py``, ``conftest.py``), so a plugin's tests may sit
    beside it."""
    name = path.name
    return not (
        name.startswith(("_", "test_")) or name.endswith("_test.py") or name == "conftest.py"
    )


@dataclass(frozen=True)
class Status:
    """Whether a plugin can be used, and why not.

    "ok"; "unavailable": a module it declares in ``requires`` is not installed (the detail names
    it and the plugin's ``install_hint``): an optional part, skipped where all plugins are
    selected; "missing dependency": its import raised ModuleNotFoundError (undeclared, so a
    typo and an absent package look alike); "import error": anything else.
    """

    state: str
    detail: str = ""


#: the kind of plugin a registry holds
Plugin = TypeVar("Plugin", "BaseDetector", "BaseProtocol")


class Registry(Generic[Plugin]):
    """Ids -> plugin classes of one kind (detector or protocol). ``base`` is their base class,
    or its "module:Class" name, imported when a plugin is first loaded."""

    def __init__(self, kind: str, base: type[Plugin] | str, group: str):
        self.kind, self.group = kind, group
        self._base: type[Plugin] | str = base
        self._sources: dict[str, Source] = {}
        self._loaded: dict[str, type[Plugin]] = {}
        self._discovered = False

    @property
    def base(self) -> type[Plugin]:
        if isinstance(self._base, str):
            module, _, attribute = self._base.partition(":")
            self._base = getattr(importlib.import_module(module), attribute)
        assert not isinstance(self._base, str)  # imported just above
        return self._base

    def _add(self, name: str, source: Source) -> None:
        if name in self._sources and self._sources[name].origin != source.origin:
            raise UsageError(
                f"two {self.kind}s are named {name!r}: one from {self._sources[name].origin}, one from {source.origin}"
            )
        self._sources[name] = source

    def _discover(self) -> None:
        if self._discovered:
            return
        self._discovered = True
        for ep in entry_points(group=self.group):
            dist = ep.dist.name if ep.dist else "?"
            package = f"{ep.dist.name} {ep.dist.version}" if ep.dist else ""
            self._add(
                ep.name, Source(f"entry point {ep.value} ({dist})", ep.value, ep.load, package)
            )

    def add_folder(self, folder: str | Path) -> None:
        """Register every plugin file of ``folder`` (:func:`is_plugin_file`); the file name
        (with - for _) is the id."""
        folder = Path(folder)
        if not folder.is_dir():
            raise UsageError(f"plugin folder {folder} does not exist")
        self._discover()
        for path in sorted(folder.glob("*.py")):
            if is_plugin_file(path):
                self._add(
                    path.stem.replace("_", "-"),
                    Source(
                        f"plugin file {path}",
                        f"file:{path.resolve()}",
                        functools.partial(import_plugin_file, path),
                    ),
                )

    def names(self) -> list[str]:
        self._discover()
        return sorted(self._sources)

    def check_name(self, name: str) -> None:
        """Refuse an id no plugin is registered under, suggesting the closest ids (difflib) and
        listing the others; imports nothing."""
        names = self.names()
        if name in names:
            return
        hint = did_you_mean(name, names)
        raise UsageError(f"unknown {self.kind} {name!r}{hint}; available: {', '.join(names)}")

    def get(self, name: str) -> type[Plugin]:
        """The plugin class registered as ``name``; an unknown name lists the names that exist."""
        if name in self._loaded:
            return self._loaded[name]
        self.check_name(name)
        source = self._sources[name]
        from slipbench.store.reads import reading

        try:
            with reading() as opened:
                obj = source.load()
        except Exception as exc:  # a broken plugin must not take the others down
            raise PluginError(
                f"{self.kind} {name!r} ({source.origin}) failed to import: {type(exc).__name__}: {exc}"
            ) from exc
        cls = obj if isinstance(obj, type) else self._class_in(obj, name, source)
        if not (isinstance(cls, type) and issubclass(cls, self.base)):
            raise PluginError(
                f"{self.kind} {name!r} ({source.origin}) is not a subclass of {self.base.__name__}"
            )
        declared = cls.__dict__.get("name")
        if declared and declared != name:
            raise PluginError(
                f"{self.kind} {name!r} ({source.origin}) declares name = {declared!r}; its id is the name "
                f"it is registered under: drop the attribute or register it as {declared!r}"
            )
        self._check_class(cls, name, source)
        _note_reads(cls, opened, f"{self.kind} {name!r} ({source.origin})")
        cls.name = (
            name  # the one source of the id, set on the class itself: a subclass gets its own
        )
        self._loaded[name] = cls
        return cls

    def _check_class(self, cls: type, name: str, source: Source) -> None:
        from slipbench.protocol import BaseProtocol, Layout, Presentation
        from slipbench.store.keys import missing_data_files

        missing = missing_data_files(cls)
        if missing:  # its cache keys would not see the files it reads
            raise PluginError(
                f"{self.kind} {name!r} ({source.origin}) declares data files that are not there: "
                f"{', '.join(missing)} (paths relative to its module's folder)"
            )
        if self.base is not BaseProtocol:
            return
        try:  # a protocol's layout may depend on its options: check the defaults'
            made = cls()
            layout, presentation = made.layout, made.presentation
        except Exception as exc:
            raise PluginError(
                f"protocol {name!r} ({source.origin}) cannot be made with its default options: "
                f"{type(exc).__name__}: {exc}"
            ) from exc
        if not isinstance(layout, Layout):
            raise PluginError(
                f"protocol {name!r} ({source.origin}) must declare layout = slipbench.protocol.Layout(...), "
                f"got {layout!r}"
            )
        if presentation is not None and not isinstance(presentation, Presentation):
            raise PluginError(
                f"protocol {name!r} ({source.origin}) must declare presentation = "
                f"slipbench.protocol.Presentation(...) or none, got {presentation!r}"
            )

    def _class_in(self, module, name: str, source: Source) -> type[Plugin]:
        found = [
            c
            for c in vars(module).values()
            if isinstance(c, type)
            and issubclass(c, self.base)
            and c is not self.base
            and c.__module__ == module.__name__
        ]
        leaves = [c for c in found if not any(o is not c and issubclass(o, c) for o in found)]
        if len(leaves) == 1:  # a module may hold a plugin's own base class beside the plugin
            return leaves[0]
        raise PluginError(
            f"{self.kind} {name!r} ({source.origin}) must define one {self.base.__name__} subclass, found {len(found)}"
        )

    def id_of(self, cls: type) -> str:
        """The id of a plugin class: the name it was loaded under, the entry point or plugin
        file that points at it, or (a class never registered) its kebab-case class name."""
        if cls.__dict__.get("name"):
            return cls.__dict__["name"]
        self._discover()
        target = f"{cls.__module__}:{cls.__qualname__}"
        for name, source in self._sources.items():
            if source.target == target or (name in self._loaded and self._loaded[name] is cls):
                return name
        from slipbench.base import plugin_id

        return plugin_id(cls)

    def status(self, name: str) -> Status:
        """Load ``name`` and say whether it can run: its import and its declared ``requires``."""
        try:
            self.get(name)
        except PluginError as exc:
            missing = exc.__cause__
            if isinstance(missing, ModuleNotFoundError):
                return Status("missing dependency", f"{missing.name} ({exc})")
            return Status("import error", str(exc))
        why = self.unavailable(name)
        return Status("unavailable", why) if why else Status("ok")

    def unavailable(self, name: str) -> str:
        """What an importable plugin lacks to run here: the modules of its ``requires`` that are
        not installed, and its ``install_hint`` (e.g. "needs aeon; install it with: pip install
        'slipbench[minirocket]'"); "" when nothing is absent."""
        cls = self.get(name)
        absent = [m for m in cls.requires if importlib.util.find_spec(m.split(".")[0]) is None]
        if not absent:
            return ""
        hint = f"; install it with: {cls.install_hint}" if cls.install_hint else ""
        return f"needs {', '.join(absent)}{hint}"

    def provenance(self, name: str) -> str:
        """Where ``name`` comes from, in words: ``built in (slipbench 0.1.0)``, the package and
        version that installed it (``labslip 1.2``), or its plugin file."""
        self._discover()
        source = self._sources[name]
        if source.package and source.target.startswith(("slipbench.", "slipbench:")):
            return f"built in ({source.package})"
        return source.package or source.origin

    def describe(self, name: str, check: bool = True) -> dict[str, Any]:
        """Id, status, one-line description and parameters with defaults (``slipbench list``);
        for a detector also its ``inputs`` and whether it is the ``reference``. Unless ``check``,
        an entry point's plugin is read from its source (:mod:`slipbench.engine.declared`), not
        imported, where its declaration is plain; ``read`` says which ("source" or "import")."""
        if not check and name not in self._loaded:
            found = self._declared(name)
            if found is not None:
                return found
        status = self.status(name)
        out: dict[str, Any] = {
            "name": name,
            "status": status.state,
            "detail": status.detail,
            "origin": self._sources[name].origin,
            "package": self._sources[name].package,
            "from": self.provenance(name),
            "description": "",
            "parameters": {},
            "read": "import",
        }
        if name in self._loaded:
            from slipbench.base import BaseDetector
            from slipbench.params import param_defaults

            cls = self._loaded[name]
            out["description"] = summary(cls.__doc__ or "")
            if issubclass(cls, BaseDetector):  # what it reads (evaluate --input), its mark
                out["inputs"] = list(cls.inputs)
                out["reference"] = bool(cls.reference)
            constraints = cls._parameter_constraints
            out["parameters"] = {
                p: {
                    "default": None if d is inspect.Parameter.empty else d,
                    "constraint": str(constraints[p]) if p in constraints else "",
                }
                for p, d in param_defaults(cls).items()
            }
        return out

    def _declared(self, name: str) -> dict[str, Any] | None:
        """:meth:`describe` from an entry point's source; None where it needs importing."""
        from slipbench.engine.declared import NeedsImport, declaration

        source = self._sources[name]
        if source.target.startswith("file:"):  # a plugin file is the user's: imported, checked
            return None
        base = (
            self._base
            if isinstance(self._base, str)
            else f"{self._base.__module__}:{self._base.__name__}"
        )
        module, _, cls = base.partition(":")
        try:
            found = declaration(source.target, (module, cls))
        except (NeedsImport, SyntaxError, OSError):
            return None
        attributes = found["attributes"]
        absent = [
            m
            for m in attributes.get("requires", ())
            if importlib.util.find_spec(m.split(".")[0]) is None
        ]
        hint = (
            f"; install it with: {attributes['install_hint']}"
            if attributes.get("install_hint")
            else ""
        )
        out: dict[str, Any] = {
            "name": name,
            "status": "unavailable" if absent else "ok",
            "detail": f"needs {', '.join(absent)}{hint}" if absent else "",
            "origin": source.origin,
            "package": source.package,
            "from": self.provenance(name),
            "description": summary(found["description"]),
            "parameters": {},
            "read": "source",
        }
        if module == "slipbench.base":  # a detector: what it reads, its mark
            out["inputs"] = list(attributes.get("inputs", ("univariate",)))
            out["reference"] = bool(attributes.get("reference", False))
        constraints = attributes.get("_parameter_constraints", {})
        out["parameters"] = {
            p: {"default": d, "constraint": constraints.get(p, "")}
            for p, d in found["parameters"].items()
        }
        return out


def summary(doc: str) -> str:
    """A docstring's first sentence, whole (it may span lines), as plain text: ``code`` and
    :role:`target` marks dropped. A sentence ends at a full stop followed by a capital or
    ``code``, or at the end of the first paragraph."""
    paragraph = " ".join(inspect.cleandoc(doc).split("\n\n")[0].split())
    text = re.sub(r":\w+:`~?([^`]+)`", r"\1", paragraph)
    return re.split(r"(?<=[.!?])\s+(?=[A-Z`])", text, maxsplit=1)[0].replace("``", "")


#: the built-in and installed plugins; the groups are those of slipbench's pyproject.toml (the
#: detectors' is ``slipbench.base.DETECTOR_GROUP``, which saved models are loaded through)
detectors: Registry[BaseDetector] = Registry(
    "detector", "slipbench.base:BaseDetector", "slipbench.detectors"
)
protocols: Registry[BaseProtocol] = Registry(
    "protocol", "slipbench.protocol:BaseProtocol", "slipbench.protocols"
)


def add_plugin_folder(folder: str | Path) -> None:
    """Register a user's plugin folder.

    It may mirror the project's layout (``detectors/`` and ``protocols/`` subfolders); a folder
    with neither holds detectors.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise UsageError(f"plugin folder {folder} does not exist")
    subfolders: list[tuple[Path, Registry[Any]]] = [
        (folder / "detectors", detectors),
        (folder / "protocols", protocols),
    ]
    if not any(sub.is_dir() for sub, _ in subfolders):
        subfolders = [(folder, detectors)]
    for sub, registry in subfolders:
        if sub.is_dir():
            registry.add_folder(sub)
