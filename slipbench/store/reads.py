"""Files a plugin reads while it is imported or fitted, seen through Python's audit hooks.

A plugin may load code or data in ways no import statement shows (``importlib`` from a path,
``exec``, ``np.load`` of a file beside it). :func:`reading` records the files opened, compiled or
executed inside it; :mod:`slipbench.store.keys` adds those read at import to the plugin's code
identity, and a fit names those that are in no identity. Audit hooks cannot be removed, so one
hook is installed per process and does nothing unless a context variable holds a collector.
"""

from __future__ import annotations

import os
import site
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from functools import cache
from pathlib import Path

_COLLECTOR: ContextVar[set[str] | None] = ContextVar("slipbench_reads", default=None)
_installed = False
_WRITE_MODES = frozenset("wax")


def _hook(event: str, args: tuple) -> None:
    opened = _COLLECTOR.get()
    if opened is None:  # the common case, kept to one lookup: the hook sees every event
        return
    path = _read_path(event, args)
    if path is not None:
        opened.add(path)


def _read_path(event: str, args: tuple) -> str | None:
    """The file an audit event reads: ``open`` for reading, ``compile`` or ``exec`` of a file's
    code (``importlib`` runs a cached module with ``exec`` and never opens its source)."""
    if event == "open":
        path, mode, flags = args
        if mode is None:
            writing = isinstance(flags, int) and flags & os.O_ACCMODE == os.O_WRONLY
        else:
            writing = "+" not in mode and not _WRITE_MODES.isdisjoint(mode)
        named = isinstance(path, (str, bytes, os.PathLike))
        return os.fsdecode(path) if named and not writing else None
    if event == "compile":
        return _file_name(args[1])
    if event == "exec":
        return _file_name(getattr(args[0], "co_filename", None))
    return None


def _file_name(name: object) -> str | None:
    if isinstance(name, bytes):
        name = os.fsdecode(name)
    return name if isinstance(name, str) and name and not name.startswith("<") else None


def install() -> None:
    """Install the hook in this process (once; later calls do nothing)."""
    global _installed
    if not _installed:
        sys.addaudithook(_hook)
        _installed = True


@contextmanager
def reading() -> Iterator[set[str]]:
    """Record the files read inside the block into the yielded set (an enclosing block gets
    them too)."""
    install()
    outer, opened = _COLLECTOR.get(), set[str]()
    token = _COLLECTOR.set(opened)
    try:
        yield opened
    finally:
        _COLLECTOR.reset(token)
        if outer is not None:
            outer |= opened


def plugin_files(opened: set[str]) -> list[Path]:
    """The files among ``opened`` that may be a plugin's own: not Python's or an installed
    library's, not a bytecode cache or a distribution's metadata (entry points read by the
    registry, an editable install's ``*.egg-info`` beside its code), not a device or process
    file; resolved and sorted."""
    roots = _library_roots()
    out = set()
    for name in opened:
        path = Path(name).resolve()
        if _not_plugin_data(path) or not path.is_file():
            continue
        if not any(path.is_relative_to(root) for root in roots):
            out.add(path)
    return sorted(out)


def _not_plugin_data(path: Path) -> bool:
    return any(
        part == "__pycache__" or part.endswith((".egg-info", ".dist-info"))
        for part in path.parts[:-1]
    )


@cache
def _library_roots() -> tuple[Path, ...]:
    prefixes = {sys.prefix, sys.base_prefix, sys.exec_prefix, *site.getsitepackages()}
    if site.ENABLE_USER_SITE and site.USER_SITE:
        prefixes.add(site.USER_SITE)
    system = ("/proc", "/sys", "/dev")
    return tuple(Path(p).resolve() for p in (*prefixes, *system))
