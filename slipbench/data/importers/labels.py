"""Per-sample slip labels of an imported file, as the mapping's ``[labels]`` says: from a label
column, or from slip segments (a segments table, or a file's ``slip_onset``/``slip_offset``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from slipbench.data.importers.mapping import CsvMapping
from slipbench.data.importers.tables import column_numbers, line_of, read_csv
from slipbench.errors import DataError, UsageError


def labels_of_file(
    m: CsvMapping,
    fields: dict,
    segments: list,
    frame: pd.DataFrame,
    rate: float,
    times: np.ndarray | None,
    path: Path,
) -> np.ndarray | None:
    """One file's per-sample labels (int8, -1 unlabelled), or None where it has none."""
    if "column" in m.labels:
        return _label_column(m, frame, path)
    segments = list(segments)
    if fields.get("slip_onset") is not None:
        segments.append(
            (fields["slip_onset"], fields.get("slip_offset"), f"{m.where}: slip_onset of {path}")
        )
    return _segment_labels(m, segments, len(frame), rate, times, path)


def _label_column(m: CsvMapping, frame: pd.DataFrame, path: Path) -> np.ndarray:
    column = m.labels["column"]
    if column not in frame.columns:
        raise DataError(f"{path}: label column {column!r} not found")
    codes = {str(v): 1 for v in m.labels["slip"]}
    codes.update({str(v): 0 for v in m.labels.get("no_slip", [])})
    codes.update({str(v): -1 for v in m.labels.get("unlabelled", [])})
    text = frame[column]
    labels = text.map(codes).to_numpy(np.float64, na_value=np.nan, copy=True)
    labels[text.isna().to_numpy()] = -1  # an empty cell is unlabelled
    bad = np.isnan(labels)
    if bad.any():
        row = int(np.argmax(bad))
        raise DataError(
            f"{path}: line {line_of(path, row, m.csv)}: column {column!r}: label {text.iloc[row]!r} is not one of "
            f"the mapping's slip {list(m.labels['slip'])}, no_slip {list(m.labels.get('no_slip', []))} "
            f"or unlabelled {list(m.labels.get('unlabelled', []))}"
        )
    return labels.astype(np.int8)


def _segment_labels(
    m: CsvMapping,
    segments: list[tuple[float, float | None, str]],
    n: int,
    rate: float,
    times: np.ndarray | None,
    path: Path,
) -> np.ndarray | None:
    """Labels from (onset, offset, where) segments: 1 inside [onset, offset), 0 before and
    between, after the last offset as [labels].after_offset says."""
    if not segments:
        return (
            None if m.labels.get("unlisted", "unlabelled") == "unlabelled" else np.zeros(n, np.int8)
        )
    in_seconds = m.labels.get("unit", "sample") == "s"
    t = times if times is not None else np.arange(n) / rate

    def sample(x: float) -> int:
        if not in_seconds:
            return int(round(x))
        return int(np.searchsorted(t, x - 1e-6 / rate, side="left"))

    labels = np.zeros(n, np.int8)
    last = 0
    for onset, offset, where in sorted(segments, key=lambda s: s[0]):
        lo, hi = sample(onset), n if offset is None else sample(offset)
        if not 0 <= lo < hi <= n or lo < last:
            raise DataError(
                f"{where}: slip segment [{onset:g}, {'end' if offset is None else f'{offset:g}'}) does not fit "
                f"{path} ({n} samples) after the previous segment"
            )
        labels[lo:hi] = 1
        last = hi
    if m.labels.get("after_offset", "no-slip") == "unlabelled":
        labels[last:] = -1
    return labels


def segments_table(m: CsvMapping) -> dict[str, list[tuple[float, float | None, str]]]:
    """file (relative to SRC) -> its segments, from the [labels].segments table."""
    name = m.labels.get("segments")
    if not isinstance(name, str):
        return {}
    path = m.base / name
    if not path.is_file():
        raise UsageError(f"{m.where}: [labels].segments: {path} not found")
    csv = {"delimiter": ",", "comment": "#", "skip_rows": 0}
    frame = read_csv(path, csv, ["file"], min_rows=1)
    for column in ("file", "onset"):
        if column not in frame.columns:
            raise DataError(
                f"{path}: column {column!r} missing (a segments table has columns file, onset, offset)"
            )
    onset = column_numbers(frame, "onset", path, csv)
    offset = (
        pd.to_numeric(frame["offset"], errors="coerce").to_numpy(np.float64, na_value=np.nan)
        if "offset" in frame.columns
        else np.full(len(frame), np.nan)
    )
    if "offset" in frame.columns:
        bad = frame["offset"].notna().to_numpy() & ~np.isfinite(offset)
        if bad.any():
            row = int(np.argmax(bad))
            raise DataError(
                f"{path}: line {line_of(path, row, csv)}: column 'offset': non-numeric value {frame['offset'].iloc[row]!r}"
            )
    table: dict[str, list] = {}
    for row, (file, lo, hi) in enumerate(zip(frame["file"], onset, offset)):
        where = f"{path}: line {line_of(path, row, csv)}"
        table.setdefault(str(file), []).append(
            (float(lo), None if np.isnan(hi) else float(hi), where)
        )
    return table
