"""The CSV importer: the files under SRC that a mapping selects become one dataset folder.

One CSV file is one recording (or one per channel group when ``[[channels]]`` lists several
units recorded together), with its metadata from the mapping, its channels, its sampling rate
and its per-sample labels. Everything goes through :func:`slipbench.data.write.write_dataset`:
validated, then written atomically.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from slipbench.data.health import (
    DROPPED_KEY,
    LEADING_KEY,
    TIMING_KEY,
    dropped_summary,
    leading_summary,
    timing,
    timing_summary,
)
from slipbench.data.importers.labels import (
    label_choice,
    labels_of_file,
    leading_slip,
    segments_table,
)
from slipbench.data.importers.mapping import (
    TIME_UNITS,
    CsvFile,
    CsvMapping,
    default_id,
    file_fields,
    file_variables,
    fill_template,
    load_mapping,
)
from slipbench.data.importers.metadata import MetadataReader
from slipbench.data.importers.paths import check_inside
from slipbench.data.importers.regular import regular
from slipbench.data.importers.tables import column_numbers, line_of, read_csv
from slipbench.data.write import write_dataset
from slipbench.errors import DataError, UsageError
from slipbench.vocabulary import SENSOR_TYPE


def import_csv(
    src: str | Path,
    out: str | Path,
    config: str | Path | Mapping | CsvMapping,
    base: Path | None = None,
    description: Mapping[bytes, str] | None = None,
) -> Path:
    """Convert the CSV files under ``src`` into a dataset folder ``out`` as the mapping says.

    Parameters
    ----------
    src : folder holding the files; ``files`` globs and rule paths are relative to it.
    out : the new dataset folder (must not exist or be empty).
    config : the mapping: a TOML file, the same structure as a dict (see ``datasets.md``), or
        one :func:`load_mapping` read (to give it outside folders, or a card's name).
    base : folder that relative paths in the mapping start from [default: the TOML file's];
        a mapping already read keeps its own.
    description : source and citation for the dataset's metadata (see ``write_dataset``).

    Every path the mapping leads to stays inside ``src`` (a segments table: inside ``base``)
    or a folder the mapping was given as outside, symbolic links followed
    (:mod:`~slipbench.data.importers.paths`).

    Raises
    ------
    UsageError : the mapping is wrong, or one of its paths leads out (its file, key and value
        named).
    DataError : a file is wrong (its path, line and column named), or the result breaks the format.
    """
    src = Path(src)
    m = config if isinstance(config, CsvMapping) else load_mapping(config, base)
    if not src.is_dir():
        raise DataError(f"{src}: not a folder")
    files = sorted(set().union(*(_glob(src, g, m, f"files = {g!r}") for g in m.files)))
    if not files:
        raise DataError(f"{src}: no file matches files = {list(m.files)}")
    selected = [
        _glob(src, r.glob, m, f"{r.name}.glob = {r.glob!r}") if r.glob else set(files)
        for r in m.rules
    ]
    metadata = MetadataReader(src, m.where, set(files), m.outside)
    segments = segments_table(m)
    for name, parts in segments.items():
        if name not in files:
            raise DataError(
                f"{parts[0][2]}: file {name!r} is not among the imported files (paths relative to SRC, with /)"
            )
    text_columns = [m.labels["column"]] if "column" in m.labels else []

    rows: list[dict[str, Any]] = []
    samples: dict[str, np.ndarray] = {}
    labels: dict[str, np.ndarray] = {}
    origin: dict[str, str] = {}  # recording_id -> the file that gave it
    timings: dict[str, dict] = {}  # file -> what its time column showed (gaps, rate)
    leading: dict[str, tuple[str, int, float]] = {}  # file -> leading slip: route, rows, s
    held = 0  # hold-slip files
    repeated: dict[str, tuple[int, int]] = {}  # file -> rows, rows drop_repeats dropped
    for rel in files:
        path = src / rel
        fields = file_fields(m, rel, selected, metadata)
        frame = read_csv(path, m.csv, text_columns)
        rate, times = _rate(m, fields, frame, path)
        file = CsvFile(path, rel, fields, frame, rate, times, file_variables(m, rel, selected))
        if times is not None:
            # a rate stated is checked against the rows over their times, unless repeats are
            # dropped (the times are the logger's then, the rate the sensor's)
            stated = not (_from_times(m, fields) or m.rate.get("drop_repeats"))
            timings[rel] = timing(times, rate if stated else None)
        file_labels = labels_of_file(m, file, segments.get(rel, []))
        recordings, file_labels = regular(
            m, file, _recordings_of(m, file, file_labels), file_labels, repeated
        )
        if recordings and recordings[0][0]["scenario"] == "hold-slip":
            held += 1
            recordings, file_labels, leading[rel] = _lead(m, file, recordings, file_labels)
        for row, values in recordings:
            rid = row["recording_id"]
            if rid in origin:
                raise UsageError(
                    f"{m.where}: {origin[rid]} and {rel} both give recording_id {rid!r}; set recording_id to tell them apart"
                )
            origin[rid] = rel
            rows.append(row)
            samples[rid] = values
            if file_labels is not None:
                labels[rid] = file_labels
    if timings:  # kept with the dataset, so that validate, info and check can say it
        summary = timing_summary(timings)
        if "resample_hz" in m.rate:
            summary["resampled_hz"] = float(m.rate["resample_hz"])
        description = {**(description or {}), TIMING_KEY.encode(): json.dumps(summary)}
    if repeated:
        description = {
            **(description or {}),
            DROPPED_KEY.encode(): json.dumps(dropped_summary(repeated)),
        }
    cut = {f: v for f, v in leading.items() if v[1]}
    if cut:  # every row the route took, counted and kept with the dataset
        description = {
            **(description or {}),
            LEADING_KEY.encode(): json.dumps(leading_summary(cut, held)),
        }
    return write_dataset(out, pd.DataFrame(rows), samples, labels or None, description)


def _glob(src: Path, pattern: str, m: CsvMapping, key: str) -> set[str]:
    """Paths (relative to ``src``, with /) of the files a glob selects, each checked to lie
    inside ``src`` (or an outside folder the mapping was given) once links are followed."""
    try:
        found = [p for p in src.glob(pattern) if p.is_file()]
    except (ValueError, NotImplementedError) as exc:
        raise UsageError(
            f"{m.where}: glob {pattern!r}: {exc} (globs are relative to SRC)"
        ) from None
    for path in found:
        check_inside(path, src, f"{m.where}: {key}", m.outside)
    return {p.relative_to(src).as_posix() for p in found}


def _channel_names(frame: pd.DataFrame, group: dict[str, Any], path: Path) -> list[str]:
    present = [str(c) for c in frame.columns]
    if "names" in group:
        missing = [n for n in group["names"] if n not in present]
        if missing:
            raise DataError(
                f"{path}: column {missing[0]!r} not found (columns: {', '.join(present[:12])}{', ...' if len(present) > 12 else ''})"
            )
        names = list(group["names"])
    else:
        names = [c for c in present if group["pattern"].fullmatch(c)]
        if not names:
            raise DataError(
                f"{path}: no column matches the channel pattern {group['pattern'].pattern!r} (columns: {', '.join(present[:12])})"
            )
    if "count" in group and len(names) != group["count"]:
        raise DataError(
            f"{path}: {len(names)} channel columns ({names[0]} ... {names[-1]}), the mapping expects {group['count']}"
        )
    return names


def _rate(
    m: CsvMapping, fields: dict, frame: pd.DataFrame, path: Path
) -> tuple[float, np.ndarray | None]:
    """Sampling rate of one file (a field, [rate].hz, or the median step of its time column) and
    its times in seconds from the first sample, when it has a time column."""
    times = None
    if "time_column" in m.rate:
        column = m.rate["time_column"]
        if column not in frame.columns:
            raise DataError(f"{path}: time column {column!r} not found")
        t = (
            column_numbers(frame, column, path, m.csv).astype(np.float64)
            * TIME_UNITS[m.rate.get("time_unit", "s")]
        )
        step = np.diff(t)
        if (step <= 0).any():
            row = int(np.argmax(step <= 0)) + 1
            raise DataError(
                f"{path}: line {line_of(path, row, m.csv)}: column {column!r}: time does not increase "
                f"({t[row - 1]:g} then {t[row]:g} s)"
            )
        times = t - t[0]
    if fields.get("sampling_rate_hz") is not None:
        return fields["sampling_rate_hz"], times
    if "hz" in m.rate:
        return float(m.rate["hz"]), times
    if times is not None:  # 12 significant digits: no floating-point noise of the differences
        return float(f"{1.0 / np.median(np.diff(times)):.12g}"), times
    raise UsageError(
        f"{m.where}: no sampling rate for {path}: give [rate] hz = ... or time_column = ..., or a sampling_rate_hz field"
    )


def _from_times(m: CsvMapping, fields: dict) -> bool:
    """Whether a file's rate was the median step of its time column (else stated)."""
    return fields.get("sampling_rate_hz") is None and "hz" not in m.rate


def _recordings_of(
    m: CsvMapping, file: CsvFile, labels: np.ndarray | None
) -> list[tuple[dict, np.ndarray]]:
    """(metadata row, samples) of each recording in one file: one per channel group."""
    rel, path, fields, frame, rate = file.rel, file.path, file.fields, file.frame, file.rate
    file_id = str(fields.get("recording_id", default_id(rel)))
    out = []
    for i, group in enumerate(m.channels):
        meta = {**fields, **_group_fields(m, file, group, i)}
        for key in (SENSOR_TYPE, "sensor_instance", "scenario"):
            if meta.get(key) in (None, ""):
                raise UsageError(
                    f"{m.where}: no {key} for {rel}: set it in [recording] or a [[rules]] that selects the file"
                )
        names = _channel_names(frame, group, path)
        values = [column_numbers(frame, c, path, m.csv) for c in names]
        units = group.get("units", "raw")
        units = [units] * len(names) if isinstance(units, str) else list(units)
        if len(units) != len(names):
            raise UsageError(
                f"{m.where}: [channels].units lists {len(units)} units for {len(names)} channels of {path}"
            )
        several = len(m.channels) > 1
        row = dict(
            recording_id=f"{file_id}/{meta['sensor_instance']}" if several else file_id,
            sensor_type=str(meta[SENSOR_TYPE]),
            sensor_instance=str(meta["sensor_instance"]),
            scenario=str(meta["scenario"]),
            material=_text(meta.get("material")),
            speed_mm_s=meta.get("speed_mm_s"),
            sampling_rate_hz=rate,
            channels=tuple(names),
            units=tuple(str(u) for u in units),
            source=_text(meta.get("source")),
            # the units of one file were recorded together: one trial unless the mapping says
            trial=_text(meta.get("trial")) or (file_id if several else None),
        )
        integers = all(
            v.dtype.kind == "i" for v in values
        )  # raw counts stay integers, written exactly
        out.append(
            (row, np.column_stack(values if integers else [v.astype(np.float64) for v in values]))
        )
    return out


def _group_fields(m: CsvMapping, file: CsvFile, group: dict, i: int) -> dict[str, Any]:
    """A channel group's ``sensor_instance`` and ``sensor_type``, templates filled and values
    mapped as [recording]'s are."""
    section = "[channels]" if len(m.channels) == 1 else f"[[channels]] #{i + 1}"
    out = {}
    for key in ("sensor_instance", SENSOR_TYPE):
        if key in group:
            value = group[key]
            if isinstance(value, str):
                value = fill_template(m, file.rel, file.variables, value, f"{section}.{key}")
            out[key] = m.maps.get(key, {}).get(value, value)
    return out


def _lead(
    m: CsvMapping, file: CsvFile, recordings: list[tuple[dict, np.ndarray]], labels: Any
) -> tuple[list[tuple[dict, np.ndarray]], np.ndarray, tuple[str, int, float]]:
    """A hold-slip file's recordings and labels with its leading slip (the rows before its
    first no-slip sample, where it starts in slip) dropped or unlabelled as ``leading_slip``
    says, and (route, rows, seconds) of what it took."""
    k = leading_slip(m, file.fields, labels, file.path)
    if not k:
        return recordings, labels, ("", 0, 0.0)
    route = label_choice(m, file.fields, "leading_slip", file.path)
    seconds = k / float(recordings[0][0]["sampling_rate_hz"])
    if route == "trim":
        return [(row, v[k:]) for row, v in recordings], labels[k:], (route, k, seconds)
    labels = labels.copy()
    labels[:k] = -1
    return recordings, labels, (route, k, seconds)


def _text(value: Any) -> str | None:
    return None if value is None or value == "" else str(value)
