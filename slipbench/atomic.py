"""Files that readers see whole or not at all, made with the user's umask, a folder lock, and
Parquet files opened with their column names checked (:func:`open_parquet`) and read with their
text checked (:func:`whole_text`).

Every file is first written under a unique hidden temporary name in its own folder (created
with ``O_EXCL``, so two processes never share one), flushed to disk, then renamed over the
target: a reader, or a run killed at any moment, sees the old file or the new one, never a torn
one. Unlike ``tempfile.mkstemp`` (mode 0600) and ``mkdtemp`` (0700), files are created with
mode 0666 and folders 0777 *through the umask* (and any default ACL), exactly as ``open(2)`` and
``mkdir(2)`` would make them, so shared lab and CI folders stay readable to the group.

An OSError that is the machine's fault (disk full, read-only, permission) becomes an
:class:`~slipbench.errors.EnvironmentFault` naming the target path; a failed write leaves no
temporary file behind (a process killed by SIGKILL cannot clean up: its hidden ``.*.tmp`` file
is ignored by every reader).
"""

from __future__ import annotations

import errno
import os
import secrets
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import TYPE_CHECKING, BinaryIO

from slipbench.errors import (
    ENVIRONMENT_ERRNOS,
    DataError,
    EnvironmentFault,
    UsageError,
    environment_fault,
    writing,
)

if TYPE_CHECKING:  # pyarrow is imported by the functions that write or read Parquet: a
    import pyarrow as pa  # command checks its destinations (check_writable) without it
    import pyarrow.parquet as pq

#: the folder of a results folder (slipbench.store.results) that holds its cell files
RESULTS_CELLS = "cells"

_CREATE = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0)


def _unique_file(folder: Path, name: str) -> tuple[int, Path]:
    """Create and open a new file ``.{name}.<random>.tmp`` in ``folder`` (mode 0666 & ~umask)."""
    for _ in range(100):
        tmp = folder / f".{name}.{secrets.token_hex(6)}.tmp"
        try:
            return os.open(tmp, _CREATE, 0o666), tmp
        except FileExistsError:
            continue
    raise FileExistsError(errno.EEXIST, "no unused temporary file name", os.fspath(folder))


def make_folder(path: str | os.PathLike) -> Path:
    """``mkdir -p`` through the umask; environment faults become EnvironmentFault."""
    path = Path(path)
    with writing(path, "create the folder"):
        path.mkdir(parents=True, exist_ok=True)
    return path


@contextmanager
def atomic_file(path: str | os.PathLike) -> Iterator[BinaryIO]:
    """A binary file object whose content replaces ``path`` when the block ends without error.

    The data are fsynced before the rename, so even a power loss cannot leave the new name on
    an empty file. On any error (and on KeyboardInterrupt) the temporary file is removed and
    ``path`` is left as it was.
    """
    path = Path(path)
    make_folder(path.parent)
    with writing(path):
        fd, tmp = _unique_file(path.parent, path.name)
    try:
        with writing(path):
            with os.fdopen(fd, "wb") as fh:
                yield fh
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, path)
    except BaseException:
        with suppress(OSError):
            tmp.unlink()
        raise


def write_atomic(table: pa.Table, path: str | os.PathLike) -> None:
    """Write a Parquet file so that readers see the old file or the new one, never a torn one."""
    # serialized in memory first: pyarrow writing through a Python file object calls back into
    # Python from its own threads, which has aborted interpreters at exit (apache/arrow#34314)
    import pyarrow as pa
    import pyarrow.parquet as pq

    sink = pa.BufferOutputStream()
    pq.write_table(table, sink)
    with atomic_file(path) as fh:
        fh.write(sink.getvalue())


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write a UTF-8 text file atomically (see :func:`atomic_file`)."""
    with atomic_file(path) as fh:
        fh.write(text.encode())


def unique_folder(parent: str | os.PathLike, prefix: str) -> Path:
    """Create a new hidden folder ``{prefix}<random>`` in ``parent``, through the umask (unlike
    ``tempfile.mkdtemp``'s 0700): build a folder there, then rename it into place."""
    parent = make_folder(parent)
    for _ in range(100):
        path = parent / f"{prefix}{secrets.token_hex(6)}"
        try:
            with writing(path, "create the folder"):
                path.mkdir()
            return path
        except FileExistsError:
            continue
    raise FileExistsError(errno.EEXIST, "no unused temporary folder name", os.fspath(parent))


def check_writable(path: str | os.PathLike, unless: str = "") -> None:
    """Raise EnvironmentFault (exit 5) naming ``path`` unless this process can write there: in
    the folder ``path`` where it is one, else in the folder that would hold it (its nearest
    existing ancestor, where a new folder would be made). Called before any work: it creates
    and removes one hidden file, the only test that sees permissions, ACLs, read-only mounts and
    root alike, and leaves nothing behind. ``unless``: a folder inside ``path`` whose presence
    passes (a results folder's :data:`RESULTS_CELLS`: a rerun that finds every cell stored
    writes nothing, and the run checks again once it knows what it writes).
    """
    path = Path(path)
    if unless and (path / unless).is_dir():
        return
    folder = next(p for p in (path, *path.parents) if p.exists())
    if folder != path and not folder.is_dir():
        raise UsageError(f"{path}: {folder} is a file, so no folder can be made there")
    folder = folder if folder.is_dir() else folder.parent  # a file is replaced in its folder
    try:
        fd, probe = _unique_file(folder, "slipbench-probe")
    except OSError as exc:
        where = "" if folder == path else f" (in {folder}, where it would be made)"
        if exc.errno not in ENVIRONMENT_ERRNOS:  # a place no file can be made (/proc/self/x)
            raise UsageError(
                f"{path}: no file can be written there{where}: {exc.strerror or exc}; "
                "nothing was written"
            ) from None
        raise EnvironmentFault(
            path,
            environment_fault(exc, path).cause,
            hint=f"found before any work{where}; nothing was written",
        ) from None
    os.close(fd)
    probe.unlink()


@contextmanager
def folder_lock(folder: str | os.PathLike, timeout: float = 300.0) -> Iterator[None]:
    """Hold an exclusive lock on ``folder`` (``flock`` on its ``.lock`` file) while the block runs.

    The kernel releases the lock when its holder exits, even by SIGKILL, so a killed run never
    leaves a stale lock. Waiting more than ``timeout`` seconds is an EnvironmentFault: only a
    hung process holds the lock that long (consolidating takes well under a second).
    """
    import fcntl  # POSIX (Linux, macOS); imported here so that the rest of slipbench imports anywhere

    path = Path(folder) / ".lock"
    with writing(path, "lock"):
        # O_RDWR: NFS emulates flock with byte-range locks, whose exclusive kind needs write access
        fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o666)
    try:
        deadline = time.monotonic() + timeout
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() > deadline:
                    raise EnvironmentFault(
                        path, f"another process has held this lock for over {timeout:g} s", "lock"
                    ) from None
                time.sleep(0.02)
        yield
    finally:
        os.close(fd)  # closing the descriptor releases the lock


def open_parquet(
    source: str | os.PathLike | pa.Buffer, where: str | os.PathLike | None = None, **options
) -> pq.ParquetFile:
    """``pq.ParquetFile(source, **options)`` whose column names are valid UTF-8, none twice.

    pyarrow raises UnicodeDecodeError on a name a flipped bit made invalid, and reads one of two
    columns of one name without a word (``to_pylist`` keeps the last): both are a DataError
    naming ``where`` (the file; default ``source``) and the column's position. A file pyarrow
    cannot open raises what pyarrow raises (ArrowException, OSError): the caller names it.
    """
    import pyarrow.parquet as pq

    where = os.fspath(source if where is None else where)
    try:
        pf = pq.ParquetFile(source, **options)
        names = pf.schema_arrow.names
    except UnicodeDecodeError:
        raise DataError(
            f"{where}: {_undecodable(source)}: its name is not valid UTF-8 text (the file is "
            "damaged, e.g. a flipped bit)"
        ) from None
    first: dict[str, int] = {}
    for i, name in enumerate(names):
        if name in first:
            raise DataError(
                f"{where}: columns {first[name] + 1} and {i + 1} of {len(names)} are both named "
                f"{name!r}: which one to read is not known (a bad rewrite, or a damaged file)"
            )
        first[name] = i
    return pf


def _undecodable(source: str | os.PathLike | pa.Buffer) -> str:
    """Which column has a name that is not UTF-8: 'column 2 of 12 (after 'id')'. Only for a
    message: pyarrow's dataset fragment reads the schema without decoding every name at once."""
    import pyarrow.dataset as pds
    import pyarrow.fs as pfs

    if isinstance(source, (str, os.PathLike)):
        fragment = pds.ParquetFileFormat().make_fragment(
            os.fspath(source), filesystem=pfs.LocalFileSystem()
        )
    else:
        fragment = pds.ParquetFileFormat().make_fragment(source)
    schema, previous = fragment.physical_schema, None
    for i in range(len(schema)):
        try:
            name = schema.field(i).name
        except UnicodeDecodeError:
            after = f" (after {previous!r})" if previous is not None else ""
            return f"column {i + 1} of {len(schema)}{after}"
        previous = name
    md = fragment.metadata  # a nested name (a list's element): its leaf column
    for i in range(md.num_columns):
        try:
            str(md.schema.column(i).path)
        except UnicodeDecodeError:
            return f"leaf column {i + 1} of {md.num_columns} (a field nested in a column)"
    return "a column"


def whole_text(table: pa.Table, where: str | os.PathLike, key: str | None = None) -> pa.Table:
    """``table`` itself, once every value in it is whole: a string a flipped bit left not valid
    UTF-8 is read by pyarrow without a word, and fails only where a value is converted (a
    UnicodeDecodeError, or an ArrowException, deep in a report).

    Raises
    ------
    DataError
        Naming ``where``, the column and the row (by its ``key`` column's value, where given
        and readable).
    """
    import pyarrow as pa

    try:
        table.validate(full=True)
        return table
    except pa.ArrowInvalid as exc:
        problem = " ".join(str(exc).split())
    for name in table.column_names:
        row = _first_undecodable(table.column(name))
        if row is not None:
            label = f"row {row + 1} of {table.num_rows}"
            if key in table.column_names and _first_undecodable(table.column(key)) is None:
                label += f" (key {table.column(key)[row].as_py()!r})"
            raise DataError(
                f"{os.fspath(where)}: column {name!r}, {label}: its text is not valid UTF-8 "
                "(the file is damaged, e.g. a flipped bit)"
            )
    raise DataError(f"{os.fspath(where)}: damaged values ({problem})")


def _first_undecodable(column: pa.ChunkedArray) -> int | None:
    """The first row of a string column whose bytes are not UTF-8 (None: none, or not text)."""
    import pyarrow as pa

    if not pa.types.is_string(column.type):
        return None
    for row, value in enumerate(column.cast(pa.binary()).to_pylist()):
        try:
            (value or b"").decode()
        except UnicodeDecodeError:
            return row
    return None
