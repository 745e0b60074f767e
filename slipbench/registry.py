"""Detectors and protocols by name: built-ins, entry points, and plugin folders.

A plugin is loaded only when it is selected, so one that fails to import is reported then,
with its name and the error, and never breaks start-up or the other plugins.
"""

from __future__ import annotations

import importlib
import importlib.util
import pkgutil
import sys
from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path

from .base import BaseDetector, BaseProtocol
from .errors import PluginError, UsageError


@dataclass(frozen=True)
class Source:
    origin: str  # where the name came from, for messages
    load: object  # () -> module or class


def _file_module(path: Path) -> object:
    module_name = f"slipbench_plugin_{path.stem}"
    spec = importlib.util.spec_from_file_location(module_name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module  # so process pools can pickle its classes
    spec.loader.exec_module(module)
    return module


class Registry:
    """Names -> plugin classes of one kind (detector or protocol)."""

    def __init__(self, kind: str, base: type, package: str, group: str):
        self.kind, self.base, self.package, self.group = kind, base, package, group
        self._sources: dict[str, Source] = {}
        self._loaded: dict[str, type] = {}
        self._discovered = False

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
        package = importlib.import_module(self.package)
        for info in pkgutil.iter_modules(package.__path__):
            if not info.name.startswith("_"):
                module = f"{self.package}.{info.name}"
                self._add(info.name.replace("_", "-"), Source(f"built-in {module}", lambda m=module: importlib.import_module(m)))
        for ep in entry_points(group=self.group):
            self._add(ep.name, Source(f"entry point {ep.value} ({ep.dist.name if ep.dist else '?'})", ep.load))

    def add_folder(self, folder: str | Path) -> None:
        """Register every ``*.py`` file of ``folder``; the file name (with - for _) is the name."""
        folder = Path(folder)
        if not folder.is_dir():
            raise UsageError(f"plugin folder {folder} does not exist")
        self._discover()
        for path in sorted(folder.glob("*.py")):
            if not path.name.startswith("_"):
                self._add(path.stem.replace("_", "-"), Source(f"plugin file {path}", lambda p=path: _file_module(p)))

    def names(self) -> list[str]:
        self._discover()
        return sorted(self._sources)

    def get(self, name: str) -> type:
        """The plugin class called ``name``; an unknown name lists the names that exist."""
        self._discover()
        if name in self._loaded:
            return self._loaded[name]
        if name not in self._sources:
            raise UsageError(f"unknown {self.kind} {name!r}; available: {', '.join(self.names())}")
        source = self._sources[name]
        try:
            obj = source.load()
        except Exception as exc:  # a broken plugin must not take the others down
            raise PluginError(f"{self.kind} {name!r} ({source.origin}) failed to import: {type(exc).__name__}: {exc}") from exc
        cls = obj if isinstance(obj, type) else self._class_in(obj, name, source)
        if not (isinstance(cls, type) and issubclass(cls, self.base)):
            raise PluginError(f"{self.kind} {name!r} ({source.origin}) is not a subclass of {self.base.__name__}")
        self._loaded[name] = cls
        return cls

    def _class_in(self, module, name: str, source: Source) -> type:
        found = [
            c for c in vars(module).values()
            if isinstance(c, type) and issubclass(c, self.base) and c is not self.base and c.__module__ == module.__name__
        ]
        named = [c for c in found if c.name == name]
        if len(named) == 1 or len(found) == 1:
            return (named or found)[0]
        raise PluginError(f"{self.kind} {name!r} ({source.origin}) must define one {self.base.__name__} subclass, found {len(found)}")


detectors = Registry("detector", BaseDetector, "slipbench.detectors", "slipbench.detectors")
protocols = Registry("protocol", BaseProtocol, "slipbench.protocols", "slipbench.protocols")


def add_plugin_folder(folder: str | Path) -> None:
    """Register a user's plugin folder.

    It may mirror the project's layout (``detectors/`` and ``protocols/`` subfolders); a folder
    with neither holds detectors.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise UsageError(f"plugin folder {folder} does not exist")
    subfolders = [(folder / "detectors", detectors), (folder / "protocols", protocols)]
    if not any(sub.is_dir() for sub, _ in subfolders):
        subfolders = [(folder, detectors)]
    for sub, registry in subfolders:
        if sub.is_dir():
            registry.add_folder(sub)
