"""Reading one CSV file of a lab: the table (:func:`read_csv`), a column as exact numbers
(:func:`column_numbers`), and the file line a message names (:func:`line_of`)."""

from __future__ import annotations

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
    path: Path, csv: dict[str, Any], text_columns: list[str], min_rows: int = 2
) -> pd.DataFrame:
    """The table of one CSV file as the mapping's ``csv`` settings say; ``text_columns`` stay
    text. A file that cannot be read, or with fewer than ``min_rows`` rows, is refused."""
    try:
        frame = pd.read_csv(
            path,
            sep=csv["delimiter"],
            comment=csv["comment"],
            skiprows=csv["skip_rows"],
            dtype={c: str for c in text_columns},
            low_memory=False,
        )
    except pd.errors.EmptyDataError:
        raise DataError(f"{path}: empty file (no header and no rows)") from None
    except (
        pd.errors.ParserError
    ) as exc:  # pandas names the line: "Expected 3 fields in line 17, saw 4"
        raise DataError(
            f"{path}: not a well-formed CSV file ({' '.join(str(exc).split())})"
        ) from None
    except UnicodeDecodeError as exc:
        raise DataError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise DataError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if len(frame) < min_rows:
        raise DataError(f"{path}: {len(frame)} data row(s); a recording needs at least {min_rows}")
    return frame


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
        raw = series.iloc[row]
        if pd.isna(raw):
            what = "empty or missing value"
        elif np.isinf(numeric[row]):
            what = f"non-finite value {raw!r}"
        else:
            what = f"non-numeric value {raw!r}"
    raise DataError(f"{path}: line {line_of(path, row, csv)}: column {column!r}: {what}")
