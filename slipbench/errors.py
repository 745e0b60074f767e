"""Errors that the CLI turns into one clear message and a distinct exit code.

Each exit code means one thing:

====  ===============================================================  =======================
code  meaning                                                          raised as
====  ===============================================================  =======================
0     every cell ok or skipped; ``compare`` found no regression        (no error)
1     ``compare`` found a regression                                   ``EXIT_REGRESSION``
2     bad usage or bad data (an option, a name, a file's format)       UsageError, DataError
3     a plugin failed to load, or one named is unavailable here        PluginError
4     the run finished, but cells failed or timed out (listed)         CellsFailed
5     an environment fault: disk full, read-only folder, no permission EnvironmentFault
      (or a lock another process holds too long, a failing disk, no
      network or an HTTP error for a download)
6     ``compare`` cannot decide: a figure regressed on one seed per    ``EXIT_UNDECIDED``
      side, or a pooled test could not see a regression of its
      tolerance (too few seeds or trials); it says how many would
====  ===============================================================  =======================
"""

from __future__ import annotations

import difflib
import errno
import os
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager

EXIT_OK = 0
EXIT_REGRESSION = 1
EXIT_USAGE = 2
EXIT_PLUGIN = 3
EXIT_CELLS_FAILED = 4
EXIT_ENVIRONMENT = 5
EXIT_UNDECIDED = 6


def did_you_mean(name: str, names: Iterable[str]) -> str:
    """`` (did you mean 'a' or 'b'?)`` for the (at most three) ``names`` closest to a mistyped
    ``name`` (difflib's ratio at least 0.6), or '' when none is close: every suggestion
    slipbench makes (plugin ids, commands) reads the same."""
    close = difflib.get_close_matches(name, list(names), n=3, cutoff=0.6)
    return f" (did you mean {' or '.join(map(repr, close))}?)" if close else ""


class SlipbenchError(Exception):
    """Base class: the message names what is wrong and where."""

    exit_code = EXIT_USAGE


class DataError(SlipbenchError):
    """A dataset or results file breaks its format (exit code 2)."""


class UsageError(SlipbenchError):
    """A bad option, name or parameter (exit code 2)."""


class PluginError(SlipbenchError):
    """A plugin failed to import or raised while running (exit code 3)."""

    exit_code = EXIT_PLUGIN


class DetectorOutputError(PluginError):
    """A detector returned scores that are not one probability per window."""


class CellsFailed(SlipbenchError):
    """The run finished, but some cells failed or timed out (exit code 4).

    Parameters
    ----------
    cells : one (label, status, reason) per unfinished cell; the label names the cell
        (protocol, detector, cell key).
    total : how many cells the run had.
    where : the results folder, named in the message.

    The message groups cells by status and reason, so that one detector failing in every
    cell reads as one line rather than hundreds; every distinct reason is listed.
    """

    exit_code = EXIT_CELLS_FAILED
    #: labels shown per reason; the rest are counted (every label is in ``self.cells``)
    SHOWN = 3

    def __init__(self, cells: Sequence[tuple[str, str, str]], total: int, where: str = ""):
        self.cells, self.total, self.where = list(cells), total, where
        groups: dict[tuple[str, str], list[str]] = {}
        for label, status, reason in self.cells:
            groups.setdefault((status, reason), []).append(label)
        lines = [
            f"{len(self.cells)} of {total} cells did not finish"
            + (f" (their rows, with status and reason, are in {where})" if where else "")
            + ":"
        ]
        for (status, reason), labels in groups.items():
            shown = "; ".join(labels[: self.SHOWN])
            more = f"; and {len(labels) - self.SHOWN} more" if len(labels) > self.SHOWN else ""
            lines.append(f"  {len(labels)} {status}: {reason or 'no reason given'} [{shown}{more}]")
        super().__init__("\n".join(lines))

    def __reduce__(self):  # rebuilt from its fields, not its message, when it crosses processes
        return type(self), (self.cells, self.total, self.where)


#: what a file or value nested past what Python's parsers read is told (their RecursionError)
TOO_DEEP = "nested too deeply to read (lists or tables inside one another, hundreds deep)"

# Errors that say the machine, not slipbench or its input, is at fault: more disk, another
# folder or other permissions fix them, and rerunning the same command then resumes.
ENVIRONMENT_ERRNOS: dict[int, str] = {
    errno.ENOSPC: "no space left on device",
    errno.EDQUOT: "disk quota exceeded",
    errno.EFBIG: "file too large for this file system or the process's file size limit",
    errno.EROFS: "read-only file system",
    errno.EACCES: "permission denied",
    errno.EPERM: "operation not permitted",
    errno.EIO: "input/output error (a failing disk or a lost network mount)",
}


class EnvironmentFault(SlipbenchError):
    """Disk full, a read-only folder, no permission (exit code 5).

    The message is one line naming the path, the action and the cause, e.g.
    ``cannot write out/cells/3f2a.parquet: no space left on device (ENOSPC)``, and ``hint``,
    what to do, where the caller knows it.
    """

    exit_code = EXIT_ENVIRONMENT

    def __init__(self, path: str | os.PathLike, cause: str, action: str = "write", hint: str = ""):
        self.path, self.cause, self.action, self.hint = os.fspath(path), cause, action, hint
        super().__init__(f"cannot {action} {self.path}: {cause}" + (f"; {hint}" if hint else ""))

    def __reduce__(self):  # a worker's fault reaches the parent whole (pebble, dask pickle it)
        return type(self), (self.path, self.cause, self.action, self.hint)


def environment_fault(
    exc: OSError, path: str | os.PathLike, action: str = "write"
) -> EnvironmentFault:
    """The EnvironmentFault an OSError stands for; re-raises ``exc`` when it is anything else.

    ``path`` is the file the caller meant to write (a temporary file's name would mean
    nothing to the user). Use as ``raise environment_fault(exc, path) from None``.
    """
    if exc.errno not in ENVIRONMENT_ERRNOS:
        raise exc
    return EnvironmentFault(
        path, f"{ENVIRONMENT_ERRNOS[exc.errno]} ({errno.errorcode[exc.errno]})", action
    )


@contextmanager
def writing(path: str | os.PathLike, action: str = "write") -> Iterator[None]:
    """Turn an environment OSError raised in the block into an EnvironmentFault naming ``path``;
    any other OSError passes through unchanged."""
    try:
        yield
    except OSError as exc:
        raise environment_fault(exc, path, action) from None
