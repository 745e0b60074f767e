"""Paths a mapping names (``files`` and rule globs, ``[[metadata]] table``, ``[labels]
segments``) stay inside their root: SRC, or for a segments table the mapping's own folder. No
``..``, no absolute path, and no symbolic link leading out (each path is resolved and checked),
so that nothing but the files a card's hashes vouch for, or the folder a user gave, enters a
dataset. A user's own mapping may read outside folders only where ``dataset import csv
--read-outside FOLDER`` names them; a card's mapping never may (``outside`` is None).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path, PurePosixPath, PureWindowsPath

from slipbench.errors import UsageError

OPTION = "--read-outside"


def _hint(outside: Sequence[Path] | None) -> str:
    if outside is None:
        return "a card's mapping reads only the card's own files"
    return f"to read a folder outside it, name that folder with `dataset import csv {OPTION}`"


def escapes(value: str) -> bool:
    """Whether a path or glob, as written, has a ``..`` part or is absolute."""
    parts = PurePosixPath(value.replace("\\", "/")).parts
    return ".." in parts or value.startswith(("/", "\\")) or bool(PureWindowsPath(value).drive)


def check_relative(value: str, entry: str, outside: Sequence[Path] | None) -> None:
    """Refuse a path with a ``..`` part or an absolute one, unless outside folders were given
    (then where it resolves decides). ``entry`` names it: 'FILE: KEY = VALUE'."""
    if not outside and escapes(value):
        raise UsageError(
            f"{entry}: paths here are relative to their folder and stay inside it (no '..', "
            f"no absolute path); {_hint(outside)}"
        )


def check_inside(path: Path, root: Path, entry: str, outside: Sequence[Path] | None) -> None:
    """Refuse ``path`` unless, symbolic links followed, it lies in ``root`` or an outside folder
    given; ``entry`` names where the path came from."""
    real = path.resolve()
    if any(real.is_relative_to(folder.resolve()) for folder in (root, *(outside or ()))):
        return
    shown = f"{path} leads to {real}" if real != path.absolute() else str(path)
    raise UsageError(f"{entry}: {shown}, outside {root}; {_hint(outside)}")
