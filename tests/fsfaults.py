"""Folders with faults of their own for tests: a filesystem mounted for the test (a small
tmpfs, a bind mount), and a folder seen read-only, as root or not."""

from __future__ import annotations

import os
import subprocess
from contextlib import contextmanager
from pathlib import Path

import pytest


@contextmanager
def mounted(target: Path, *options: str, source: str = "tmpfs"):
    """Mount (root only); skips the test where this machine does not allow it."""
    if os.geteuid() != 0:
        pytest.skip("mounting a filesystem needs root")
    target.mkdir(parents=True, exist_ok=True)
    done = subprocess.run(["mount", *options, source, str(target)], capture_output=True, text=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount here: {done.stderr.strip()}")
    try:
        yield target
    finally:
        subprocess.run(["umount", "-l", str(target)], check=True)


@contextmanager
def read_only(folder: Path):
    """``folder`` seen read-only: a read-only bind mount as root (root ignores permissions),
    else the folder's write permissions removed."""
    if os.geteuid() != 0:
        modes = {p: p.stat().st_mode for p in [folder, *folder.rglob("*")]}
        for p, mode in modes.items():
            p.chmod(mode & ~0o222)
        try:
            yield folder
        finally:
            for p, mode in modes.items():
                p.chmod(mode)
        return
    view = folder.with_name(folder.name + "-ro")
    with mounted(view, "--bind", source=str(folder)):
        done = subprocess.run(
            ["mount", "-o", "remount,bind,ro", str(view)], capture_output=True, text=True
        )
        if done.returncode != 0:
            pytest.skip(f"cannot remount read-only: {done.stderr.strip()}")
        yield view
