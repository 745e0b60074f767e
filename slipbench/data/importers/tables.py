"""Reading one CSV file of a lab: the table (:func:`read_csv`), a column as exact numbers
(:func:`column_numbers`), and the file line a message names (:func:`line_of`).

The reader is strict about the shape: every row holds as many fields as the header names, so a
value can never land in its neighbour's column. Delimiters at the ends of lines (the header's,
the rows', or both) are read as what they are: empty fields beyond the last named column.
"""

from __future__ import annotations

import csv as csvlib
import io
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from slipbench.data.schema import EXACT_INT
from slipbench.errors import DataError


def line_of(path: Path, row: int, csv: dict[str, Any]) -> int:
    """The file line (from 1) of data row ``row`` as pandas counts them: blank and comment lines
    are not rows. Read again only when a message needs it."""
    with open(path, encoding="utf-8", errors="replace") as fh:
        seen = -1  # -1: the header is still to come
        for number, line in enumerate(fh, start=1):
            if (
                number <= csv["skip_rows"]
                or not line.strip()
                or (csv["comment"] and line.lstrip().startswith(csv["comment"]))
            ):
                continue
            if seen == row:
                return number
            seen += 1
    return -1


def read_csv(
    path: Path, csv: dict[str, Any], text_columns: list[str], min_rows: int = 2, text: bool = False
) -> pd.DataFrame:
    """The table of one CSV file as the mapping's ``csv`` settings say; ``text_columns`` (every
    column with ``text``) stay text. A file that cannot be read, a row with a value beyond the header's last column or
    fewer fields than it names, or fewer than ``min_rows`` rows, is refused naming the line."""
    lines = _data_lines(path, csv)
    if not lines:
        raise DataError(f"{path}: empty file (no header and no rows)")
    width, n_rows = _checked_width(path, lines, csv["delimiter"])
    try:
        # index_col=False: empty fields past the last name are trailing delimiters, never an index
        frame = pd.read_csv(
            io.StringIO("".join(text for _, text in lines)),
            sep=csv["delimiter"],
            header=0,
            index_col=False,
            usecols=range(width),
            dtype=str if text else {c: str for c in text_columns},
            low_memory=False,
        )
    except pd.errors.ParserError as exc:  # e.g. an unterminated quote
        raise DataError(
            f"{path}: not a well-formed CSV file ({' '.join(str(exc).split())})"
        ) from None
    if len(frame) != n_rows:  # both parsers follow RFC 4180; a file they split apart is refused
        raise DataError(
            f"{path}: pandas reads {len(frame)} rows where the csv module reads {n_rows}: check its quoting"
        )
    if len(frame) < min_rows:
        raise DataError(f"{path}: {len(frame)} data row(s); a recording needs at least {min_rows}")
    return frame


def _data_lines(path: Path, csv: dict[str, Any]) -> list[tuple[int, str]]:
    """(file line from 1, text) of the header and the rows: lines before ``skip_rows``, blank
    lines and comment lines left out, a comment at a line's end cut off (as :func:`line_of`
    counts them)."""
    try:
        data = path.read_bytes()
        text = data.decode("utf-8-sig")  # -sig: a byte-order mark is not a name
    except UnicodeDecodeError as exc:
        raise DataError(f"{path}: {_not_utf8(data, exc, csv)}") from None
    except OSError as exc:
        raise DataError(f"{path}: cannot read ({exc.strerror or exc})") from None
    comment = csv["comment"]
    out = []
    # read_text made every line end "\n" (universal newlines), as line_of's file iteration does
    for number, line in enumerate(text.split("\n"), start=1):
        if number <= csv["skip_rows"] or not line.strip():
            continue
        if comment:
            if line.lstrip().startswith(comment):
                continue
            line = line.split(comment, 1)[0]
        out.append((number, line + "\n"))
    return out


def _not_utf8(data: bytes, exc: UnicodeDecodeError, csv: dict[str, Any]) -> str:
    """Where a byte that is not UTF-8 sits: line, and column as the delimiters count them."""
    at = exc.start + len(data) - len(exc.object)  # the decoder saw no byte-order mark
    line = data.count(b"\n", 0, at) + 1
    column = data[data.rfind(b"\n", 0, at) + 1 : at].count(csv["delimiter"].encode())
    return (
        f"line {line}, column {column + 1}: byte {at} (0x{data[at]:02x}) is not UTF-8 text "
        f"({exc.reason}): a damaged file, or one saved in another encoding (save it as UTF-8)"
    )


def _checked_width(path: Path, lines: list[tuple[int, str]], delimiter: str) -> tuple[int, int]:
    """The number of named columns and of rows; raise where a row does not fit the columns.

    The header's names end at its last non-empty field. A row may end in empty fields beyond
    them (trailing delimiters); a value there, or a row with fewer fields, would be read shifted
    or short, so it is refused."""
    reader = csvlib.reader((text for _, text in lines), delimiter=delimiter)
    consumed = rows = 0
    header_line, width = lines[0][0], 0
    try:
        for fields in reader:
            number, consumed = lines[consumed][0], reader.line_num
            if number == header_line:
                named = [i for i, f in enumerate(fields) if f.strip()]
                width = named[-1] + 1 if named else 0
                if width == 0:
                    raise DataError(f"{path}: line {number}: the header names no column")
                seen: dict[str, int] = {}
                for i, name in enumerate(fields[:width]):
                    if name.strip() and name in seen:
                        raise DataError(
                            f"{path}: line {number}: column name {name!r} appears twice in the "
                            f"header (columns {seen[name] + 1} and {i + 1})"
                        )
                    seen[name] = i
                continue
            rows += 1
            if len(fields) < width:
                raise DataError(
                    f"{path}: line {number}: {len(fields)} fields, but the header (line "
                    f"{header_line}) names {width} columns: a short row"
                )
            extra = [f for f in fields[width:] if f.strip()]
            if extra:
                raise DataError(
                    f"{path}: line {number}: {len(fields)} fields, but the header (line "
                    f"{header_line}) names {width} columns: value {extra[0]!r} has no column "
                    "(a name missing from the header, or a delimiter too many in the row); "
                    "refused rather than read with its columns shifted"
                )
    except csvlib.Error as exc:
        number = lines[min(consumed, len(lines) - 1)][0]
        raise DataError(f"{path}: line {number}: not a well-formed CSV line ({exc})") from None
    return width, rows


def column_numbers(frame: pd.DataFrame, column: str, path: Path, csv: dict[str, Any]) -> np.ndarray:
    """A column as int64 (integers stay exact) or float64; a bad cell is named by line and
    column."""
    series = frame[column]
    if series.dtype.kind in "iu":
        values = series.to_numpy(np.int64)
        if np.abs(values.astype(np.float64)).max() <= EXACT_INT:
            return values
        row = int(np.argmax(np.abs(values.astype(np.float64)) > EXACT_INT))
        what = f"integer {values[row]} beyond 2**53 (float64 cannot hold it exactly)"
    else:
        numeric = (
            pd.to_numeric(series, errors="coerce").to_numpy(np.float64, na_value=np.nan)
            if series.dtype.kind != "f"
            else series.to_numpy(np.float64, na_value=np.nan)
        )
        bad = ~np.isfinite(numeric)
        if not bad.any():
            return numeric
        row = int(np.argmax(bad))
        text = _field(path, row, list(frame.columns).index(column), csv).strip()
        if not text:
            what = "empty value"
        elif np.isinf(numeric[row]):
            what = f"non-finite value {text!r}"
        else:  # "nan", "NA", "abc": none of them a number
            what = f"non-numeric value {text!r}"
    raise DataError(f"{path}: line {line_of(path, row, csv)}: column {column!r}: {what}")


def _field(path: Path, row: int, position: int, csv: dict[str, Any]) -> str:
    """The text of data row ``row``'s field ``position`` as the file holds it (pandas reads
    "nan", "NA" and "" alike as missing, and "inf" as a float). Read again for a message only."""
    number = line_of(path, row, csv)
    text = next((t for n, t in _data_lines(path, csv) if n == number), "")
    fields = next(csvlib.reader([text], delimiter=csv["delimiter"]), [])
    return fields[position] if position < len(fields) else ""
