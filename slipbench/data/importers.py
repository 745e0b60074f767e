"""Importers into the slipbench format: a generic CSV importer driven by a mapping file, and
the published datasets as mappings of it.

The mapping (TOML, documented with a full example in ``datasets.md``) says which files to read,
the metadata of each (from the mapping, with templates filled from patterns on file paths),
which columns are channels, where the sampling rate and the per-sample labels come from, and
which files form one trial. One CSV file is one recording (or one per channel group when
``[[channels]]`` lists several units recorded together). Everything goes through
:func:`slipbench.data.dataset.write_dataset`: validated, then written atomically.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import tomllib

from slipbench.data.dataset import EXACT_INT, write_dataset
from slipbench.errors import DataError, UsageError

FIELDS = (
    "recording_id",
    "sensor_type",
    "sensor_instance",
    "scenario",
    "material",
    "speed_mm_s",
    "source",
    "trial",
    "sampling_rate_hz",
    "slip_onset",
    "slip_offset",
)
NUMERIC_FIELDS = ("speed_mm_s", "sampling_rate_hz", "slip_onset", "slip_offset")
TOP_KEYS = {
    "files",
    "delimiter",
    "comment",
    "skip_rows",
    "recording",
    "rules",
    "map",
    "channels",
    "rate",
    "labels",
}
CHANNEL_KEYS = {"names", "pattern", "count", "units", "sensor_instance", "sensor_type"}
RATE_KEYS = {"hz", "time_column", "time_unit"}
LABEL_KEYS = {
    "column",
    "slip",
    "no_slip",
    "unlabelled",
    "segments",
    "unit",
    "after_offset",
    "unlisted",
}
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}


# ----------------------------------------------------------------------------- the mapping
@dataclass(frozen=True)
class Rule:
    """Fields for the files a glob and/or a regex (on the path relative to SRC) select."""

    name: str
    glob: str | None
    regex: re.Pattern | None
    fields: dict[str, Any]


@dataclass(frozen=True)
class CsvMapping:
    """A parsed, checked mapping file."""

    where: str
    files: tuple[str, ...]
    csv: dict[str, Any]
    recording: Rule
    rules: tuple[Rule, ...]
    maps: dict[str, dict[str, Any]]
    channels: tuple[dict[str, Any], ...]
    rate: dict[str, Any]
    labels: dict[str, Any]
    base: Path


def _bad(where: str, what: str) -> UsageError:
    return UsageError(f"{where}: {what}")


def _keys(table: Any, known: set[str], where: str, section: str) -> dict:
    if not isinstance(table, dict):
        raise _bad(where, f"{section} must be a table")
    unknown = sorted(set(table) - known)
    if unknown:
        raise _bad(
            where, f"unknown key {unknown[0]!r} in {section} (known: {', '.join(sorted(known))})"
        )
    return table


def _regex(text: Any, where: str, section: str) -> re.Pattern | None:
    if text is None:
        return None
    if not isinstance(text, str):
        raise _bad(where, f"{section}.regex must be a string")
    try:
        return re.compile(text)
    except re.error as exc:
        raise _bad(where, f"{section}.regex {text!r} is not a regular expression ({exc})") from None


def _rule(table: Any, where: str, section: str, selector: bool) -> Rule:
    table = _keys(
        table, set(FIELDS) | {"regex"} | ({"glob"} if selector else set()), where, section
    )
    glob = table.get("glob")
    if glob is not None and not isinstance(glob, str):
        raise _bad(where, f"{section}.glob must be a string")
    if selector and glob is None and "regex" not in table:
        raise _bad(where, f"{section} needs a glob or a regex saying which files it applies to")
    fields = {k: v for k, v in table.items() if k in FIELDS}
    for key, value in fields.items():
        if not isinstance(value, (str, int, float)) or isinstance(value, bool):
            raise _bad(where, f"{section}.{key} must be a string or a number, got {value!r}")
    return Rule(section, glob, _regex(table.get("regex"), where, section), fields)


def load_mapping(config: str | Path | Mapping, base: Path | None = None) -> CsvMapping:
    """Parse and check a mapping: a TOML file, or the same structure as a dict.

    ``base`` is the folder relative paths in the mapping (a segments table) start from: the
    mapping file's folder, or the working folder for a dict.
    """
    if isinstance(config, Mapping):
        where, raw, base = "mapping", dict(config), Path(base or ".")
    else:
        path = Path(config)
        where = str(path)
        try:
            raw = tomllib.loads(path.read_text(encoding="utf-8"))
        except OSError as exc:
            raise UsageError(f"{path}: cannot read the mapping ({exc.strerror or exc})") from None
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise UsageError(f"{path}: not valid TOML ({exc})") from None
        base = Path(base) if base else path.parent
    _keys(raw, TOP_KEYS, where, "the mapping")
    files = raw.get("files", "**/*.csv")
    files = (files,) if isinstance(files, str) else files
    if (
        not isinstance(files, (list, tuple))
        or not files
        or not all(isinstance(f, str) for f in files)
    ):
        raise _bad(
            where, 'files must be a glob or a list of globs relative to SRC, e.g. "**/*.csv"'
        )
    csv = {
        "delimiter": raw.get("delimiter", ","),
        "comment": raw.get("comment"),
        "skip_rows": raw.get("skip_rows", 0),
    }
    if not isinstance(csv["delimiter"], str) or len(csv["delimiter"]) != 1:
        raise _bad(where, f"delimiter must be one character, got {csv['delimiter']!r}")
    if csv["comment"] is not None and (
        not isinstance(csv["comment"], str) or len(csv["comment"]) != 1
    ):
        raise _bad(where, f"comment must be one character, got {csv['comment']!r}")
    if (
        not isinstance(csv["skip_rows"], int)
        or isinstance(csv["skip_rows"], bool)
        or csv["skip_rows"] < 0
    ):
        raise _bad(where, f"skip_rows must be an int >= 0, got {csv['skip_rows']!r}")
    recording = _rule(raw.get("recording", {}), where, "[recording]", selector=False)
    rules = raw.get("rules", [])
    if not isinstance(rules, list):
        raise _bad(where, "rules must be an array of tables: [[rules]]")
    rules = tuple(
        _rule(r, where, f"[[rules]] #{i + 1}", selector=True) for i, r in enumerate(rules)
    )
    maps = _keys(raw.get("map", {}), set(FIELDS), where, "[map]")
    for key, table in maps.items():
        if not isinstance(table, dict):
            raise _bad(where, f"[map.{key}] must be a table of old = new values")
    channels = raw.get("channels")
    if channels is None:
        raise _bad(where, '[channels] is missing: give names = [...] or pattern = "..."')
    channels = tuple(channels) if isinstance(channels, list) else (channels,)
    for i, group in enumerate(channels):
        section = "[channels]" if len(channels) == 1 else f"[[channels]] #{i + 1}"
        _keys(group, CHANNEL_KEYS, where, section)
        if ("names" in group) == ("pattern" in group):
            raise _bad(where, f'{section} needs exactly one of names = [...] or pattern = "..."')
        if "names" in group and (
            not isinstance(group["names"], list)
            or not group["names"]
            or not all(isinstance(n, str) for n in group["names"])
        ):
            raise _bad(where, f"{section}.names must be a non-empty list of column names")
        if "pattern" in group:
            group = {**group, "pattern": _regex(group["pattern"], where, section)}
        if len(channels) > 1 and "sensor_instance" not in group:
            raise _bad(
                where, f"{section} needs sensor_instance: several channel groups are several units"
            )
        channels = channels[:i] + (group,) + channels[i + 1 :]
    rate = _keys(raw.get("rate", {}), RATE_KEYS, where, "[rate]")
    if "hz" in rate and (
        isinstance(rate["hz"], bool)
        or not isinstance(rate["hz"], (int, float))
        or not rate["hz"] > 0
    ):
        raise _bad(where, f"[rate].hz must be a number > 0, got {rate['hz']!r}")
    if rate.get("time_unit", "s") not in TIME_UNITS:
        raise _bad(
            where,
            f"[rate].time_unit must be one of {', '.join(TIME_UNITS)}, got {rate['time_unit']!r}",
        )
    labels = _keys(raw.get("labels", {}), LABEL_KEYS, where, "[labels]")
    if "column" in labels and "segments" in labels:
        raise _bad(where, "[labels] takes a column or segments, not both")
    if "column" in labels and not labels.get("slip"):
        raise _bad(where, "[labels].column needs slip = [...]: the values that mean slip")
    for key in ("slip", "no_slip", "unlabelled"):
        value = labels.get(key, [])
        if not isinstance(value, list) or not all(
            isinstance(v, (str, int)) and not isinstance(v, bool) for v in value
        ):
            raise _bad(
                where,
                f"[labels].{key} must be a list of values as written in the files (strings or integers)",
            )
    for key, allowed in (
        ("unit", ("sample", "s")),
        ("after_offset", ("no-slip", "unlabelled")),
        ("unlisted", ("unlabelled", "no-slip")),
    ):
        if key in labels and labels[key] not in allowed:
            raise _bad(
                where, f"[labels].{key} must be one of {', '.join(allowed)}, got {labels[key]!r}"
            )
    return CsvMapping(
        where, tuple(files), csv, recording, rules, maps, channels, rate, labels, base
    )


# ----------------------------------------------------------------------------- per file
def _fields(m: CsvMapping, rel: str, selected: list[set[str]]) -> dict[str, Any]:
    """The resolved metadata of one file: [recording], then each rule that selects it, in order;
    templates filled from path parts and named regex groups; values mapped; numbers parsed."""
    parts = rel.rsplit("/", 1)
    variables = {
        "path": _default_id(rel),
        "name": parts[-1],
        "stem": Path(parts[-1]).stem,
        "parent": parts[0] if len(parts) == 2 else "",
        "file": rel,
    }
    fields: dict[str, Any] = {}
    for rule, chosen in [(m.recording, None)] + list(zip(m.rules, selected)):
        if chosen is not None and rel not in chosen:
            continue
        if rule.regex is not None:
            match = rule.regex.fullmatch(rel)
            if match is None:
                if chosen is None:
                    raise DataError(
                        f"{rel}: the path does not match {rule.name}.regex {rule.regex.pattern!r} (paths are relative to SRC, with /)"
                    )
                continue
            groups = {k: v for k, v in match.groupdict().items() if v is not None}
            variables.update(groups)
            fields.update({k: v for k, v in groups.items() if k in FIELDS})
        fields.update(rule.fields)
    out: dict[str, Any] = {}
    for key, value in fields.items():
        if isinstance(value, str):
            try:
                value = value.format_map(variables)
            except (KeyError, IndexError, ValueError) as exc:
                raise UsageError(
                    f"{m.where}: {key} = {value!r}: no value for {exc} in {rel} (known: {', '.join(sorted(variables))})"
                ) from None
        value = m.maps.get(key, {}).get(value, value)
        if key in NUMERIC_FIELDS:
            value = _number(value, rel, key)
        out[key] = value
    return out


def _number(value: Any, rel: str, key: str) -> float | None:
    if isinstance(value, str):
        if value.strip().lower() in ("", "none", "null", "nan"):
            return None
        try:
            return float(value)
        except ValueError:
            raise DataError(f"{rel}: {key} = {value!r} is not a number") from None
    return float(value)


def _line_of(path: Path, row: int, csv: dict[str, Any]) -> int:
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


def _read_csv(
    path: Path, csv: dict[str, Any], text_columns: list[str], min_rows: int = 2
) -> pd.DataFrame:
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


def _numbers(frame: pd.DataFrame, column: str, path: Path, csv: dict[str, Any]) -> np.ndarray:
    """A column as int64 (integers stay exact) or float64; a bad cell is named by line and column."""
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
    raise DataError(f"{path}: line {_line_of(path, row, csv)}: column {column!r}: {what}")


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
            _numbers(frame, column, path, m.csv).astype(np.float64)
            * TIME_UNITS[m.rate.get("time_unit", "s")]
        )
        step = np.diff(t)
        if (step <= 0).any():
            row = int(np.argmax(step <= 0)) + 1
            raise DataError(
                f"{path}: line {_line_of(path, row, m.csv)}: column {column!r}: time does not increase "
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
            f"{path}: line {_line_of(path, row, m.csv)}: column {column!r}: label {text.iloc[row]!r} is not one of "
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


def _segments_table(m: CsvMapping) -> dict[str, list[tuple[float, float | None, str]]]:
    """file (relative to SRC) -> its segments, from the [labels].segments table."""
    name = m.labels.get("segments")
    if not isinstance(name, str):
        return {}
    path = m.base / name
    if not path.is_file():
        raise UsageError(f"{m.where}: [labels].segments: {path} not found")
    csv = {"delimiter": ",", "comment": "#", "skip_rows": 0}
    frame = _read_csv(path, csv, ["file"], min_rows=1)
    for column in ("file", "onset"):
        if column not in frame.columns:
            raise DataError(
                f"{path}: column {column!r} missing (a segments table has columns file, onset, offset)"
            )
    onset = _numbers(frame, "onset", path, csv)
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
                f"{path}: line {_line_of(path, row, csv)}: column 'offset': non-numeric value {frame['offset'].iloc[row]!r}"
            )
    table: dict[str, list] = {}
    for row, (file, lo, hi) in enumerate(zip(frame["file"], onset, offset)):
        where = f"{path}: line {_line_of(path, row, csv)}"
        table.setdefault(str(file), []).append(
            (float(lo), None if np.isnan(hi) else float(hi), where)
        )
    return table


# ----------------------------------------------------------------------------- the importer
def _glob(src: Path, pattern: str, m: CsvMapping) -> set[str]:
    """Paths (relative to ``src``, with /) of the files a glob selects."""
    try:
        return {p.relative_to(src).as_posix() for p in src.glob(pattern) if p.is_file()}
    except (ValueError, NotImplementedError) as exc:
        raise UsageError(
            f"{m.where}: glob {pattern!r}: {exc} (globs are relative to SRC)"
        ) from None


def _file_labels(
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


def _recordings_of(
    m: CsvMapping,
    rel: str,
    path: Path,
    fields: dict,
    frame: pd.DataFrame,
    rate: float,
    labels: np.ndarray | None,
) -> list[tuple[dict, np.ndarray]]:
    """(metadata row, samples) of each recording in one file: one per channel group."""
    file_id = str(fields.get("recording_id", _default_id(rel)))
    out = []
    for group in m.channels:
        meta = {**fields, **{k: group[k] for k in ("sensor_instance", "sensor_type") if k in group}}
        for key in ("sensor_type", "sensor_instance", "scenario"):
            if meta.get(key) in (None, ""):
                raise UsageError(
                    f"{m.where}: no {key} for {rel}: set it in [recording] or a [[rules]] that selects the file"
                )
        if meta["scenario"] == "hold-slip" and (labels is None or not (labels == 1).any()):
            raise DataError(
                f"{path}: scenario hold-slip needs per-sample labels with a slip onset: "
                "give [labels] a column, or segments (a table or slip_onset)"
            )
        names = _channel_names(frame, group, path)
        values = [_numbers(frame, c, path, m.csv) for c in names]
        units = group.get("units", "raw")
        units = [units] * len(names) if isinstance(units, str) else list(units)
        if len(units) != len(names):
            raise UsageError(
                f"{m.where}: [channels].units lists {len(units)} units for {len(names)} channels of {path}"
            )
        several = len(m.channels) > 1
        row = dict(
            recording_id=f"{file_id}/{meta['sensor_instance']}" if several else file_id,
            sensor_type=str(meta["sensor_type"]),
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


def import_csv(
    src: str | Path, out: str | Path, config: str | Path | Mapping, base: Path | None = None
) -> Path:
    """Convert the CSV files under ``src`` into a dataset folder ``out`` as the mapping says.

    Parameters
    ----------
    src : folder holding the files; ``files`` globs and rule paths are relative to it.
    out : the new dataset folder (must not exist or be empty).
    config : the mapping: a TOML file, or the same structure as a dict (see ``datasets.md``).
    base : folder that relative paths in the mapping start from [default: the TOML file's].

    Raises
    ------
    UsageError : the mapping is wrong (its file and key named).
    DataError : a file is wrong (its path, line and column named), or the result breaks the format.
    """
    src = Path(src)
    m = load_mapping(config, base)
    if not src.is_dir():
        raise DataError(f"{src}: not a folder")
    files = sorted(set().union(*(_glob(src, g, m) for g in m.files)))
    if not files:
        raise DataError(f"{src}: no file matches files = {list(m.files)}")
    selected = [_glob(src, r.glob, m) if r.glob else set(files) for r in m.rules]
    segments = _segments_table(m)
    for name, parts in segments.items():
        if name not in files:
            raise DataError(
                f"{parts[0][2]}: file {name!r} is not among the imported files (paths relative to SRC, with /)"
            )
    text_columns = [m.labels["column"]] if "column" in m.labels else []

    rows, samples, labels, origin = [], {}, {}, {}
    for rel in files:
        path = src / rel
        fields = _fields(m, rel, selected)
        frame = _read_csv(path, m.csv, text_columns)
        rate, times = _rate(m, fields, frame, path)
        file_labels = _file_labels(m, fields, segments.get(rel, []), frame, rate, times, path)
        for row, values in _recordings_of(m, rel, path, fields, frame, rate, file_labels):
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
    return write_dataset(out, pd.DataFrame(rows), samples, labels or None)


def _default_id(rel: str) -> str:
    """The default recording id of a file: its path relative to SRC without the extension."""
    head, _, name = rel.rpartition("/")
    stem = name.rsplit(".", 1)[0] if "." in name else name
    return f"{head}/{stem}" if head else stem


def _text(value: Any) -> str | None:
    return None if value is None or value == "" else str(value)


# ----------------------------------------------------------------------------- published datasets
BIOTACSP_DOS_MAPPING = r"""
# BioTacSP-DoS (Zapata-Impata, Gil, Torres, Sensors 19(3):523, 2019): its csvs/ folder.
files = ["n/*.csv", "e/*.csv", "s/*.csv", "w/*.csv", "cw/*.csv", "aw/*.csv", "t/*.csv"]

[recording]
regex = '(?P<direction>[a-z]+)/(?P<material>.+?)\d*\.csv'   # folder = class, file = object + number
sensor_type = "BioTacSP"
sensor_instance = "ff"
scenario = "slip"
source = "BioTacSP-DoS (Zapata-Impata et al. 2019), direction {direction}"

[[rules]]
glob = "t/*.csv"          # touch: stable contact without slip
scenario = "press"

[map.material]
strippes = "striped"      # one file name misspells the striped object

[channels]
pattern = 'ff_e\d+'
count = 24
units = "raw"

[rate]
hz = 100.0
"""


def biotacsp_dos(src: str | Path, out: str | Path, rate_hz: float = 100.0) -> Path:
    """Import BioTacSP-DoS (Zapata-Impata, Gil, Torres, Sensors 19(3):523, 2019).

    ``src`` is its ``csvs`` folder: one subfolder per class (``n e s w cw aw``: slip, ``t``:
    touch), one CSV per recording with the 24 electrode channels ``ff_e1..ff_e24``. Slip folders
    become scenario ``slip``, touch becomes ``press``; the object (the file name without its
    running number; "strippes" is the striped object) becomes ``material``; speed is unknown.
    It is :data:`BIOTACSP_DOS_MAPPING` run through :func:`import_csv`.
    """
    mapping = tomllib.loads(BIOTACSP_DOS_MAPPING)
    mapping["rate"]["hz"] = rate_hz
    return import_csv(src, out, mapping)


IMPORTERS = {"biotacsp-dos": biotacsp_dos}
