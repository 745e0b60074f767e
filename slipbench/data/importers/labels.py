"""Per-sample slip labels of an imported file, as the mapping's ``[labels]`` says: from a label
column, or from slip segments (a segments table, or a file's ``slip_onset``/``slip_offset``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from slipbench.data.importers.mapping import LABEL_CHOICES, CsvFile, CsvMapping
from slipbench.data.importers.paths import check_inside
from slipbench.data.importers.tables import column_numbers, line_of, read_csv
from slipbench.errors import DataError, UsageError

# (onset, offset or None for the end, where it was given, what follows it or None: the default)
Segment = tuple[float, float | None, str, str | None]


def labels_of_file(m: CsvMapping, file: CsvFile, segments: list) -> np.ndarray | None:
    """One file's per-sample labels (int8, -1 unlabelled), or None where it has none."""
    fields, frame, path = file.fields, file.frame, file.path
    if "column" in m.labels:
        return _label_column(m, frame, path)
    segments = list(segments)
    if fields.get("slip_onset") is not None:
        segments.append(
            (
                fields["slip_onset"],
                fields.get("slip_offset"),
                f"{m.where}: slip_onset of {path}",
                None,
            )
        )
    return _segment_labels(m, file, segments)


def label_choice(m: CsvMapping, fields: dict, key: str, path: Path) -> str:
    """A file's after_offset, unlisted or leading_slip: its own field (from [recording], [[rules]] or a
    metadata table) or [labels]'s, checked here since a template may fill it."""
    value = fields.get(key, m.labels.get(key, LABEL_CHOICES[key][0]))
    if value not in LABEL_CHOICES[key]:
        raise UsageError(
            f"{m.where}: {key} of {path} is {value!r}; it must be one of {', '.join(LABEL_CHOICES[key])}"
        )
    return str(value)


def leading_slip(m: CsvMapping, fields: dict, labels: np.ndarray | None, path: Path) -> int:
    """Rows of a hold-slip file before its hold (its first no-slip sample) that ``leading_slip``
    (``trim`` or ``unlabelled``) takes: 0 where the labels hold before any slip. Refused where
    there is no hold at all, or where they start in slip and ``leading_slip`` is ``refuse``."""
    if labels is None:
        raise DataError(
            f"{path}: scenario hold-slip needs per-sample labels: give [labels] a column, or "
            'segments (a table or slip_onset), or unlisted = "no-slip" for a trial that never slips'
        )
    held, slipping = np.flatnonzero(labels == 0), np.flatnonzero(labels == 1)
    if not len(held):
        raise DataError(
            f"{path}: scenario hold-slip: no sample labelled no-slip before "
            + ("the slip onset" if len(slipping) else "the end (and no slip)")
            + ": the trial has no hold"
            + (
                "; a trial that slips throughout is scenario slip (a [[rules]] for it)"
                if len(slipping)
                else ""
            )
        )
    if not len(slipping) or slipping[0] > held[0]:
        return 0
    route = label_choice(m, fields, "leading_slip", path)
    if route == "refuse":
        raise DataError(
            f"{path}: scenario hold-slip: the trial starts in slip ({held[0]} rows before its first "
            'no-slip sample): [labels] leading_slip = "trim" drops those rows, "unlabelled" keeps '
            "them unlabelled; either is counted in the import's warnings"
        )
    return int(held[0])


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


def _segment_labels(m: CsvMapping, file: CsvFile, segments: list[Segment]) -> np.ndarray | None:
    """Labels from (onset, offset, where, after) segments: 1 inside [onset, offset), 0 before;
    what follows a segment up to the next one (or the end) as its ``after`` says, else no slip
    between segments and the file's after_offset after the last."""
    fields, n, rate, times, path = file.fields, len(file.frame), file.rate, file.times, file.path
    if not segments:
        return (
            None
            if label_choice(m, fields, "unlisted", path) == "unlabelled"
            else np.zeros(n, np.int8)
        )
    file_after = label_choice(m, fields, "after_offset", path)
    in_seconds = m.labels.get("unit", "sample") == "s"
    t = times if times is not None else np.arange(n) / rate

    def sample(x: float) -> int:
        if not in_seconds:
            return int(round(x))
        return int(np.searchsorted(t, x - 1e-6 / rate, side="left"))

    labels = np.zeros(n, np.int8)
    last = 0
    ordered = sorted(segments, key=lambda s: s[0])
    for k, (onset, offset, where, after) in enumerate(ordered):
        lo, hi = sample(onset), n if offset is None else sample(offset)
        if not 0 <= lo < hi <= n or lo < last:
            raise DataError(
                f"{where}: slip segment [{onset:g}, {'end' if offset is None else f'{offset:g}'}) does not fit "
                f"{path} ({n} samples) after the previous segment"
            )
        labels[lo:hi] = 1
        last = hi
        until = sample(ordered[k + 1][0]) if k + 1 < len(ordered) else n
        if (after or ("no-slip" if k + 1 < len(ordered) else file_after)) == "unlabelled":
            labels[hi:until] = -1  # a drop, or a stretch nobody labelled
    return labels


def segments_table(m: CsvMapping) -> dict[str, list[Segment]]:
    """file (relative to SRC) -> its segments, from the [labels].segments table; an optional
    column ``after_offset`` says what follows a segment (empty: the default)."""
    name = m.labels.get("segments")
    if not isinstance(name, str):
        return {}
    path = m.base / name
    check_inside(path, m.base, f"{m.where}: [labels].segments = {name!r}", m.outside)
    if not path.is_file():
        raise UsageError(f"{m.where}: [labels].segments: {path} not found")
    csv = {"delimiter": ",", "comment": "#", "skip_rows": 0}
    frame = read_csv(path, csv, ["file", "after_offset"], min_rows=1)
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
    after = frame["after_offset"] if "after_offset" in frame.columns else [None] * len(frame)
    table: dict[str, list] = {}
    for row, (file, lo, hi, then) in enumerate(zip(frame["file"], onset, offset, after)):
        where = f"{path}: line {line_of(path, row, csv)}"
        then = None if pd.isna(then) or not str(then).strip() else str(then).strip()
        if then is not None and then not in LABEL_CHOICES["after_offset"]:
            raise DataError(
                f"{where}: column 'after_offset': {then!r} is not one of "
                f"{', '.join(LABEL_CHOICES['after_offset'])} (or empty)"
            )
        table.setdefault(str(file), []).append(
            (float(lo), None if np.isnan(hi) else float(hi), where, then)
        )
    return table
