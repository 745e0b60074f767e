"""How the data wing says what is wrong: one line naming the file (or the in-memory dataset),
the recording and the column, and plain numbers and ids inside it."""

from __future__ import annotations

from pathlib import Path

from slipbench.errors import DataError


def data_error(
    where: str | Path, what: str, recording: str | None = None, column: str | None = None
) -> DataError:
    """A :class:`DataError` saying ``where: recording 'r': column 'c': what``."""
    parts = [str(where)]
    if recording is not None:
        parts.append(f"recording {str(recording)!r}")
    if column is not None:
        parts.append(f"column {column!r}")
    return DataError(f"{': '.join(parts)}: {what}")


def plain_number(x: float) -> str:
    """A plain number for messages: 60, 59.738499926 (never ``np.float64(...)``)."""
    return f"{float(x):.12g}"


def some_names(ids, limit: int = 3) -> str:
    """The first ``limit`` ids, quoted, and how many more: 'a', 'b', 'c' and 4 more."""
    ids = [str(i) for i in ids]
    shown = ", ".join(repr(i) for i in ids[:limit])
    return shown + (f" and {len(ids) - limit} more" if len(ids) > limit else "")


def one_line(exc: BaseException) -> str:
    """An exception's text on one line (Arrow's messages span several)."""
    return " ".join(str(exc).split())
