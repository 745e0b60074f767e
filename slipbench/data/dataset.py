"""The Parquet dataset format, version 1: reading, validating and writing.

A dataset is a folder holding two Parquet files (see ``datasets.md``):

``recordings.parquet``
    one row per recording: ``recording_id``, ``sensor_type``, ``sensor_instance``,
    ``scenario`` (one of :data:`SCENARIOS`), ``material``, ``speed_mm_s``, ``sampling_rate_hz``,
    ``channels``, ``units``, ``source`` and optionally ``trial``.
``samples.parquet``
    one row per sample: ``recording_id``, ``sample_index`` (0, 1, ... per recording, rows in any
    order), ``values`` (one number per channel) and optionally ``slip`` (bool; null = unlabelled).

Both files carry ``slipbench.format_version = "1"`` in their schema metadata. The reader takes
every Arrow flavour of strings (string, large_string, string_view, dictionary) and lists (list,
large_list, fixed_size_list) that pandas, pyarrow and Polars write, and gives the same
:class:`Dataset`, with the same fingerprint, whatever the row order of either file.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from slipbench.errors import DataError
from slipbench.vocabulary import sensor_pairs

FORMAT_VERSION = "1"
VERSION_KEY = b"slipbench.format_version"
RECORDINGS_FILE = "recordings.parquet"
SAMPLES_FILE = "samples.parquet"
SCENARIOS = ("slip", "press", "free-space", "hold-slip")
# Rates of one unit may differ by this fraction of the lowest and still pool (at their median).
# A logger's clock and dropped frames move a nominal 60 Hz between 59.7 and 60.0 Hz (0.5 %);
# a changed rate setting moves it by far more (50 -> 60 Hz is 20 %). 1 % moves a 100 ms window
# by at most 1 ms and a frequency by 1 %, less than one bin of a window shorter than 100 samples.
RATE_TOLERANCE = 0.01
# Integers beyond 2**53 have no exact float64: refused rather than rounded.
EXACT_INT = 2**53

RECORDINGS_SCHEMA = pa.schema(
    [
        ("recording_id", pa.string()),
        ("sensor_type", pa.string()),
        ("sensor_instance", pa.string()),
        ("scenario", pa.string()),
        ("material", pa.string()),
        ("speed_mm_s", pa.float64()),
        ("sampling_rate_hz", pa.float64()),
        ("channels", pa.list_(pa.string())),
        ("units", pa.list_(pa.string())),
        ("source", pa.string()),
        ("trial", pa.string()),
    ]
)
FORMAT_COLUMNS = tuple(RECORDINGS_SCHEMA.names)
# Columns that may be absent from the file: a recording is then its own trial; its length is
# then not checked (written by write_dataset, it catches rows lost at a recording's end).
OPTIONAL = {"trial", "n_samples"}
N_SAMPLES = pa.field("n_samples", pa.int64())
# Columns that may hold nulls: free-space has no material, pressing has no speed.
NULLABLE = {"material", "speed_mm_s", "source", "trial"}
STRING_COLUMNS = (
    "recording_id",
    "sensor_type",
    "sensor_instance",
    "scenario",
    "material",
    "source",
    "trial",
)
# Derived by the reader: channels per recording, and the rate every recording of a unit pools at.
DERIVED_COLUMNS = ("n_channels", "unit_rate_hz", "n_samples")
IN_MEMORY = "in-memory dataset"


@dataclass(eq=False)
class Dataset:
    """Recordings metadata plus each recording's samples and labels, validated and canonical.

    Built by :func:`read_dataset` or in memory; both give the same canonical form: recordings
    sorted by ``recording_id``, integer samples as float64, labels as int8.

    Attributes
    ----------
    recordings : DataFrame, one row per recording, sorted by ``recording_id``: the columns of
        :data:`RECORDINGS_SCHEMA` (``trial`` always present: a recording without one is its own
        trial), ``channels``/``units`` as tuples, ``n_channels``, ``n_samples`` and
        ``unit_rate_hz`` (the median rate of the recording's unit, see :data:`RATE_TOLERANCE`).
    samples : dict recording_id -> array of shape (n_samples, n_channels); float32 where the
        file holds float32 (or float16), float64 where it holds float64 or integers.
    slip_labels : dict recording_id -> int8 array of shape (n_samples,): -1 unlabelled, 0 no
        slip, 1 slip. Every recording has one when the file has a ``slip`` column; empty when not.
    path : where the dataset was read from (None if built in memory).
    """

    recordings: pd.DataFrame
    samples: dict[str, np.ndarray]
    slip_labels: dict[str, np.ndarray] = field(default_factory=dict)
    path: Path | None = None

    def __post_init__(self) -> None:
        self.path = None if self.path is None else Path(self.path)
        where = (
            (self.path / RECORDINGS_FILE, self.path / SAMPLES_FILE)
            if self.path
            else (IN_MEMORY, IN_MEMORY)
        )
        self.recordings, self.samples, self.slip_labels = _canonical(
            self.recordings, self.samples, self.slip_labels, *where
        )

    @cached_property
    def fingerprint(self) -> str:
        """Content hash: the same recordings give the same 16 hex digits however they were
        stored (row order, Arrow flavours, pyarrow version) or built in memory.

        Computed on first use and cached: change no array of a Dataset after reading it. Costs
        about 1 s for the simulated design at scale 0.2 (12 M samples, 46 M values): 2 x
        BLAKE2b over the bytes of its files (``benchmarks/bench_data.py``).
        """
        return content_fingerprint(self.recordings, self.samples, self.slip_labels)

    def sensors(self) -> list[tuple[str, str]]:
        """(sensor_type, sensor_instance) pairs in order of first appearance."""
        return sensor_pairs(self.recordings)


# ----------------------------------------------------------------------------- messages
def _fail(
    where: str | Path, what: str, recording: str | None = None, column: str | None = None
) -> DataError:
    parts = [str(where)]
    if recording is not None:
        parts.append(f"recording {str(recording)!r}")
    if column is not None:
        parts.append(f"column {column!r}")
    return DataError(f"{': '.join(parts)}: {what}")


def _num(x: float) -> str:
    """A plain number for messages: 60, 59.738499926 (never ``np.float64(...)``)."""
    return f"{float(x):.12g}"


def _names(ids, limit: int = 3) -> str:
    ids = [str(i) for i in ids]
    shown = ", ".join(repr(i) for i in ids[:limit])
    return shown + (f" and {len(ids) - limit} more" if len(ids) > limit else "")


# ----------------------------------------------------------------------------- Arrow flavours
def _is_string(t: pa.DataType) -> bool:
    return (
        pa.types.is_string(t)
        or pa.types.is_large_string(t)
        or pa.types.is_string_view(t)
        or (pa.types.is_dictionary(t) and _is_string(t.value_type))
    )


def _is_list(t: pa.DataType) -> bool:
    return pa.types.is_list(t) or pa.types.is_large_list(t) or pa.types.is_fixed_size_list(t)


def _is_number(t: pa.DataType) -> bool:
    return pa.types.is_integer(t) or pa.types.is_floating(t)


def _nullable(check):
    return lambda t: check(t) or pa.types.is_null(t)


RECORDING_TYPES = {
    "recording_id": (_is_string, "a string"),
    "sensor_type": (_is_string, "a string"),
    "sensor_instance": (_is_string, "a string"),
    "scenario": (_is_string, "a string"),
    "material": (_nullable(_is_string), "a string"),
    "speed_mm_s": (_nullable(_is_number), "a number"),
    "sampling_rate_hz": (_is_number, "a number"),
    "channels": (lambda t: _is_list(t) and _is_string(t.value_type), "a list of strings"),
    "units": (lambda t: _is_list(t) and _is_string(t.value_type), "a list of strings"),
    "source": (_nullable(_is_string), "a string"),
    "trial": (_nullable(_is_string), "a string"),
    "n_samples": (_nullable(pa.types.is_integer), "an integer"),
}


def _open_parquet(file: Path) -> pq.ParquetFile:
    """Open a Parquet file of the format, checking its version; columns are read later, one row
    group at a time, so that reading a large dataset never holds every column at once."""
    if not file.is_file():
        raise DataError(
            f"{file}: missing (a slipbench dataset folder holds {RECORDINGS_FILE} and {SAMPLES_FILE})"
        )
    try:
        pf = pq.ParquetFile(file)
        schema = pf.schema_arrow
    except (pa.ArrowException, OSError) as exc:
        raise DataError(f"{file}: not a readable Parquet file ({_one_line(exc)})") from None
    version = (schema.metadata or {}).get(VERSION_KEY)
    if version is None:
        raise _fail(
            file, f"no {VERSION_KEY.decode()} in the schema metadata; is this a slipbench dataset?"
        )
    if version.decode(errors="replace") != FORMAT_VERSION:
        raise _fail(
            file,
            f"format version {version.decode(errors='replace')!r} is not supported (this slipbench reads {FORMAT_VERSION!r})",
        )
    return pf


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())


def _check_type(schema: pa.Schema, file: Path, name: str, check, type_name: str) -> None:
    if name not in schema.names:
        raise _fail(
            file,
            f"required column missing (columns present: {', '.join(schema.names)})",
            column=name,
        )
    if not check(schema.field(name).type):
        raise _fail(file, f"must be {type_name}, found {schema.field(name).type}", column=name)


# ----------------------------------------------------------------------------- recordings
def _read_recordings(file: Path) -> tuple[pd.DataFrame, dict[str, int]]:
    """The canonical recordings, and the lengths the file declares (its ``n_samples``)."""
    table = _open_parquet(file).read()
    columns = {}
    for name, (check, type_name) in RECORDING_TYPES.items():
        if name in OPTIONAL and name not in table.column_names:
            continue
        _check_type(table.schema, file, name, check, type_name)
        columns[name] = table.column(name).to_pylist()  # plain Python values: every flavour alike
    declared = columns.pop("n_samples", [])
    rec = _canonical_recordings(pd.DataFrame(columns), file)
    return rec, {rid: n for rid, n in zip(columns["recording_id"], declared) if n is not None}


def _canonical_recordings(frame: pd.DataFrame, where: str | Path) -> pd.DataFrame:
    """Validate a recordings table and bring it to the canonical form (see :class:`Dataset`)."""
    missing = [c for c in FORMAT_COLUMNS if c not in frame.columns and c not in OPTIONAL]
    if missing:
        raise _fail(
            where,
            f"required column missing (columns present: {', '.join(map(str, frame.columns))})",
            column=missing[0],
        )
    n = len(frame)
    if n == 0:
        raise _fail(where, "no recordings")
    cols: dict[str, list] = {}
    for name in FORMAT_COLUMNS:
        values = list(frame[name]) if name in frame.columns else [None] * n
        # a NaN rate is a bad number, not a missing one; elsewhere NaN is how pandas says null
        missing = (lambda v: v is None or v is pd.NA) if name == "sampling_rate_hz" else _is_null
        cols[name] = [None if missing(v) else v for v in values]
    ids = cols["recording_id"]
    for name in FORMAT_COLUMNS:
        for i, v in enumerate(cols[name]):
            if v is None and name not in NULLABLE:
                raise _fail(where, "null value", None if name == "recording_id" else ids[i], name)
    for name in STRING_COLUMNS:
        for i, v in enumerate(cols[name]):
            if v is not None and not isinstance(v, str):
                raise _fail(
                    where, f"must be a string, found {type(v).__name__} {v!r}", ids[i], name
                )
            if v == "" and name in ("recording_id", "sensor_type", "sensor_instance"):
                raise _fail(where, "empty string", None if name == "recording_id" else ids[i], name)
    seen: set[str] = set()
    for rid in ids:
        if rid in seen:
            raise _fail(where, "recording_id is not unique", rid, "recording_id")
        seen.add(rid)
    for rid, scenario in zip(ids, cols["scenario"]):
        if scenario not in SCENARIOS:
            raise _fail(
                where,
                f"scenario {scenario!r} is not one of {', '.join(SCENARIOS)}",
                rid,
                "scenario",
            )
    rate = _floats(cols["sampling_rate_hz"], ids, where, "sampling_rate_hz")
    bad = ~(np.isfinite(rate) & (rate > 0))
    if bad.any():
        i = int(np.argmax(bad))
        raise _fail(
            where,
            f"sampling rate must be a finite positive number, got {_num(rate[i])}",
            ids[i],
            "sampling_rate_hz",
        )
    speed = _floats(cols["speed_mm_s"], ids, where, "speed_mm_s")
    bad = ~np.isnan(speed) & ~(np.isfinite(speed) & (speed >= 0))
    if bad.any():
        i = int(np.argmax(bad))
        raise _fail(
            where, f"speed must be finite and >= 0, got {_num(speed[i])}", ids[i], "speed_mm_s"
        )
    for name in ("channels", "units"):
        cols[name] = [_strings(v, rid, where, name) for rid, v in zip(ids, cols[name])]
    n_ch = np.array([len(c) for c in cols["channels"]], dtype=np.int64)
    for rid, channels, units in zip(ids, cols["channels"], cols["units"]):
        if not channels:
            raise _fail(where, "no channels", rid, "channels")
        if len(units) != len(channels):
            raise _fail(
                where,
                f"units must list one unit per channel ({len(channels)} channels, {len(units)} units)",
                rid,
                "units",
            )
    cols["trial"] = [rid if t is None else t for rid, t in zip(ids, cols["trial"])]
    cols["speed_mm_s"], cols["sampling_rate_hz"] = speed, rate
    out = pd.DataFrame(cols)
    out["n_channels"] = n_ch
    for name in frame.columns:  # a caller's own columns ride along (the format ignores them)
        if name not in out.columns and name not in DERIVED_COLUMNS:
            out[name] = frame[name].to_numpy()
    out = out.iloc[np.argsort(np.array(ids, dtype=object), kind="stable")].reset_index(drop=True)
    out["unit_rate_hz"] = _unit_rates(out, where)
    return out


def _is_null(v: Any) -> bool:
    return v is None or (isinstance(v, float) and np.isnan(v)) or v is pd.NA or v is pd.NaT


def _floats(values: list, ids: list, where, name: str) -> np.ndarray:
    out = np.full(len(values), np.nan)
    for i, v in enumerate(values):
        if v is None:
            continue
        if isinstance(v, (bool, np.bool_)) or not isinstance(
            v, (int, float, np.integer, np.floating)
        ):
            raise _fail(where, f"must be a number, found {type(v).__name__} {v!r}", ids[i], name)
        out[i] = float(v)
    return out


def _strings(value: Any, rid: str, where, name: str) -> tuple[str, ...]:
    if isinstance(value, str) or not hasattr(value, "__iter__"):
        raise _fail(where, f"must be a list of strings, found {type(value).__name__}", rid, name)
    items = tuple(value)
    for item in items:
        if not isinstance(item, str):
            raise _fail(
                where,
                f"must be a list of strings, found {'null' if _is_null(item) else repr(item)} in it",
                rid,
                name,
            )
    return items


def _unit_rates(rec: pd.DataFrame, where) -> np.ndarray:
    """The median rate of each recording's unit; a unit whose rates spread beyond
    :data:`RATE_TOLERANCE` of its lowest is refused, naming the recordings at both ends."""
    out = np.empty(len(rec))
    rates = rec["sampling_rate_hz"].to_numpy(dtype=float)
    ids = rec["recording_id"].to_numpy(dtype=object)
    for (sensor, unit), rows in rec.groupby(
        ["sensor_type", "sensor_instance"], sort=True
    ).indices.items():
        r = rates[rows]
        lo, hi = r.min(), r.max()
        if hi > lo * (1 + RATE_TOLERANCE):
            raise _fail(
                where,
                f"sensor {sensor!r} unit {unit!r}: sampling rates differ by {100 * (hi / lo - 1):.3g} %, more than "
                f"RATE_TOLERANCE ({100 * RATE_TOLERANCE:g} %): lowest {_num(lo)} Hz in recording(s) {_names(ids[rows][r == lo])}, "
                f"highest {_num(hi)} Hz in recording(s) {_names(ids[rows][r == hi])}; a unit recorded at two settings "
                "is two units (give each its own sensor_instance)",
                column="sampling_rate_hz",
            )
        out[rows] = np.median(r)
    return out


# ----------------------------------------------------------------------------- samples
def _codes(chunk: pa.Array, index: pd.Index, file: Path, row0: int) -> np.ndarray:
    """Row -> position of its recording in the canonical recordings, for one chunk."""
    if chunk.null_count:
        raise _fail(file, f"null value at row {row0 + _first_null(chunk)}", column="recording_id")
    if not pa.types.is_dictionary(chunk.type):
        chunk = pc.dictionary_encode(chunk.cast(pa.large_string()))
    names = chunk.dictionary.cast(pa.string()).to_numpy(zero_copy_only=False)
    lookup = index.get_indexer(names)
    indices = chunk.indices.to_numpy(zero_copy_only=False)
    if (lookup < 0).any():
        used = np.zeros(len(names), bool)
        used[indices] = True
        unknown = used & (lookup < 0)
        if unknown.any():
            raise _fail(
                file,
                f"recording not listed in {RECORDINGS_FILE}",
                names[np.argmax(unknown)],
                "recording_id",
            )
    return lookup[indices].astype(np.int64)


def _first_null(array: pa.Array) -> int:
    # not is_null().to_numpy(): Arrow booleans convert to NumPy slowly (0.3 s per million)
    return pc.index(array.is_null(), True).as_py()


def _row_groups(pf: pq.ParquetFile, columns: list[str]) -> Iterator[tuple[int, pa.Table]]:
    """(first row, table) for each row group: a large file never sits in memory whole."""
    row0 = 0
    for group in range(pf.num_row_groups):
        table = pf.read_row_group(group, columns=columns)
        yield row0, table
        row0 += table.num_rows


def _labels_of(
    chunk: pa.Array, file: Path, ids: np.ndarray, codes: np.ndarray, index: np.ndarray
) -> np.ndarray:
    """A ``slip`` chunk as int8: -1 null (unlabelled), 0, 1."""
    if pa.types.is_null(chunk.type):
        return np.full(len(chunk), -1, np.int8)
    ints = pc.cast(chunk, pa.int64())
    given = pc.fill_null(ints, 0).to_numpy()
    bad = (given != 0) & (given != 1)
    if bad.any():
        i = int(np.argmax(bad))
        raise _fail(
            file,
            f"slip must be true/false (or 1/0), or null for unlabelled; sample_index {int(index[i])} has {int(given[i])}",
            ids[codes[i]],
            "slip",
        )
    return pc.fill_null(ints, -1).to_numpy().astype(np.int8)


def _read_samples(file: Path, rec: pd.DataFrame, declared: Mapping[str, int]) -> tuple[dict, dict]:
    """Every recording's samples and labels, placed by ``sample_index`` whatever the row order;
    ``declared``: recording_id -> the n_samples that recordings.parquet gives."""
    pf = _open_parquet(file)
    schema = pf.schema_arrow
    _check_type(schema, file, "recording_id", _is_string, "a string")
    _check_type(schema, file, "sample_index", pa.types.is_integer, "an integer")
    _check_type(
        schema,
        file,
        "values",
        lambda t: _is_list(t) and _is_number(t.value_type),
        "a list of numbers (list, large_list or fixed_size_list of integers or floats)",
    )
    has_slip = "slip" in schema.names
    if has_slip:
        _check_type(
            schema,
            file,
            "slip",
            lambda t: pa.types.is_boolean(t) or pa.types.is_integer(t) or pa.types.is_null(t),
            "bool (null for unlabelled)",
        )
    value_type = schema.field("values").type.value_type
    is_int = pa.types.is_integer(value_type)
    dtype = np.float32 if value_type in (pa.float16(), pa.float32()) else np.float64
    ids = rec["recording_id"].to_numpy(dtype=object)
    index = pd.Index(ids)
    n_ch = rec["n_channels"].to_numpy()

    # 1. rows per recording
    n_rows = pf.metadata.num_rows
    if n_rows == 0:
        raise _fail(file, "no samples")
    counts = np.zeros(len(ids), np.int64)
    for row0, table in _row_groups(pf, ["recording_id"]):
        for chunk in table.column(0).chunks:
            counts += np.bincount(_codes(chunk, index, file, row0), minlength=len(ids))
            row0 += len(chunk)
    if (counts == 0).any():
        raise _fail(file, "recording has no samples", ids[np.argmax(counts == 0)], "recording_id")
    for k, rid in enumerate(ids):  # the writer's record of each length: rows lost at an end show
        if rid in declared and declared[rid] != counts[k]:
            raise _fail(
                file,
                f"{int(counts[k])} rows, but {RECORDINGS_FILE} gives n_samples {declared[rid]}: rows are missing "
                "or left over",
                rid,
                "sample_index",
            )
    if (counts < 2).any():
        raise _fail(
            file, "a recording needs at least 2 samples", ids[np.argmax(counts < 2)], "sample_index"
        )
    row_start = np.r_[0, np.cumsum(counts)]
    elem_start = np.r_[0, np.cumsum(counts * n_ch)]

    # 2. each row group's rows go where their recording and sample_index say
    flat = np.empty(int(elem_start[-1]), dtype)
    filled = np.zeros(n_rows, bool)
    labels = np.full(n_rows, -1, np.int8) if has_slip else None
    for row0, table in _row_groups(
        pf, ["recording_id", "sample_index", "values"] + (["slip"] if has_slip else [])
    ):
        if table.num_rows == 0:
            continue
        table = table.combine_chunks()
        codes = _codes(table.column("recording_id").chunk(0), index, file, row0)
        si_arr = table.column("sample_index").chunk(0)
        if si_arr.null_count:
            i = _first_null(si_arr)
            raise _fail(file, f"null value at row {row0 + i}", ids[codes[i]], "sample_index")
        si = si_arr.to_numpy().astype(np.int64)
        bad = (si < 0) | (si >= counts[codes])
        if bad.any():
            i = int(np.argmax(bad))
            raise _fail(
                file,
                f"sample_index {int(si[i])} (row {row0 + i}) is out of range: the recording has {int(counts[codes[i]])} "
                f"rows, so its indices must be 0 to {int(counts[codes[i]]) - 1}, each once",
                ids[codes[i]],
                "sample_index",
            )
        dest = row_start[codes] + si
        again = filled[dest] | _repeated(dest)
        if again.any():
            i = int(np.argmax(again))
            raise _fail(
                file,
                f"sample_index {int(si[i])} appears more than once",
                ids[codes[i]],
                "sample_index",
            )
        filled[dest] = True
        _place_values(
            table.column("values").chunk(0),
            file,
            ids,
            codes,
            si,
            n_ch,
            elem_start,
            flat,
            is_int,
            row0,
        )
        if has_slip:
            labels[dest] = _labels_of(table.column("slip").chunk(0), file, ids, codes, si)

    samples: dict[str, np.ndarray] = {}
    slip: dict[str, np.ndarray] = {}
    for k, rid in enumerate(ids):
        samples[rid] = flat[elem_start[k] : elem_start[k + 1]].reshape(int(counts[k]), int(n_ch[k]))
        if labels is not None:
            slip[rid] = labels[row_start[k] : row_start[k + 1]]
    return samples, slip


def _repeated(x: np.ndarray) -> np.ndarray:
    """True where a value already appeared earlier in ``x``."""
    ordered = np.sort(
        x, kind="stable"
    )  # timsort: a few ms on rows in order, 70 ms per million shuffled
    if not (ordered[1:] == ordered[:-1]).any():
        return np.zeros(len(x), bool)
    order = np.argsort(x, kind="stable")
    dup = np.zeros(len(x), bool)
    dup[order[1:]] = x[order[1:]] == x[order[:-1]]
    return dup


def _place_values(
    chunk: pa.Array, file: Path, ids, codes, si, n_ch, elem_start, flat, is_int: bool, row0: int
) -> None:
    """Check one chunk of ``values`` (widths, nulls, finite, exact) and copy it into ``flat``."""
    if chunk.null_count:
        i = _first_null(chunk)
        raise _fail(
            file, f"null list of values at sample_index {int(si[i])}", ids[codes[i]], "values"
        )
    if pa.types.is_fixed_size_list(chunk.type):
        widths = np.full(len(chunk), chunk.type.list_size, np.int64)
    else:  # offsets, not pc.list_value_length: ten times faster on a million rows
        widths = np.diff(chunk.offsets.to_numpy()).astype(np.int64)
    bad = widths != n_ch[codes]
    if bad.any():
        i = int(np.argmax(bad))
        raise _fail(
            file,
            f"sample_index {int(si[i])} (row {row0 + i}) has {int(widths[i])} values but the recording has "
            f"{int(n_ch[codes[i]])} channels",
            ids[codes[i]],
            "values",
        )
    part = chunk.flatten()
    ends = np.cumsum(widths)

    def row_of(element: int) -> int:
        return int(np.searchsorted(ends, element, side="right"))

    if part.null_count:
        i = row_of(_first_null(part))
        raise _fail(
            file, f"null channel value at sample_index {int(si[i])}", ids[codes[i]], "values"
        )
    raw = part.to_numpy()
    if is_int:
        too_big = np.abs(raw.astype(np.float64)) > EXACT_INT
        if too_big.any():
            i = row_of(int(np.argmax(too_big)))
            raise _fail(
                file,
                f"integer beyond 2**53 at sample_index {int(si[i])}: float64 cannot hold it exactly",
                ids[codes[i]],
                "values",
            )
    values = raw.astype(flat.dtype, copy=False)
    finite = np.isfinite(values)
    if not finite.all():
        i = row_of(int(np.argmin(finite)))
        raise _fail(
            file,
            f"non-finite value (NaN or infinity) at sample_index {int(si[i])}",
            ids[codes[i]],
            "values",
        )
    # where each row's values go: its recording's block, plus sample_index rows of it
    row_pos = elem_start[codes] + si * widths
    first = ends - widths
    jumps = np.flatnonzero(np.diff(row_pos) != widths[:-1]) + 1
    if len(jumps) <= max(16, len(row_pos) // 1024):  # rows mostly in order: copy runs as slices
        bounds = np.r_[0, jumps, len(row_pos)]
        for a, b in zip(bounds[:-1], bounds[1:]):
            flat[row_pos[a] : row_pos[a] + ends[b - 1] - first[a]] = values[first[a] : ends[b - 1]]
    else:  # shuffled rows: one scatter of every element
        flat[np.repeat(row_pos - first, widths) + np.arange(len(values))] = values


# ----------------------------------------------------------------------------- canonical form
def _canonical(
    recordings: pd.DataFrame,
    samples: Mapping[str, np.ndarray],
    slip_labels: Mapping[str, np.ndarray] | None,
    rec_where: str | Path,
    samples_where: str | Path,
) -> tuple[pd.DataFrame, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Validated canonical recordings, samples and labels; cheap when they already are (no copies)."""
    rec = _canonical_recordings(recordings, rec_where)
    ids = rec["recording_id"].tolist()
    out_samples: dict[str, np.ndarray] = {}
    for rid, channels in zip(ids, rec["n_channels"].to_numpy()):
        if rid not in samples:
            raise _fail(samples_where, "recording has no samples", rid, "recording_id")
        a = np.asarray(samples[rid])
        if a.dtype.kind in "iu":
            a = a.astype(np.float64)
        elif a.dtype == np.float16:
            a = a.astype(np.float32)
        elif a.dtype not in (np.float32, np.float64):
            raise _fail(
                samples_where, f"samples must be numbers, found dtype {a.dtype}", rid, "values"
            )
        if a.ndim != 2 or a.shape[1] != channels or len(a) < 2:
            raise _fail(
                samples_where,
                f"samples must have shape (n >= 2, {int(channels)} channels), found {a.shape}",
                rid,
                "values",
            )
        out_samples[rid] = a
    labels: dict[str, np.ndarray] = {}
    if slip_labels:
        unknown = set(slip_labels) - set(ids)
        if unknown:
            raise _fail(
                samples_where,
                f"labels of a recording not listed in {RECORDINGS_FILE}",
                sorted(unknown)[0],
                "slip",
            )
        for rid in ids:
            labels[rid] = _canonical_labels(
                slip_labels.get(rid), len(out_samples[rid]), rid, samples_where
            )
    for rid, scenario in zip(ids, rec["scenario"]):
        if scenario == "hold-slip":
            _check_onset(labels.get(rid), rid, samples_where)
    rec["n_samples"] = np.array([len(out_samples[rid]) for rid in ids], np.int64)
    return rec, out_samples, labels


def _canonical_labels(labels, n: int, rid: str, where) -> np.ndarray:
    if labels is None:
        return np.full(n, -1, np.int8)
    a = np.asarray(labels)
    if a.dtype == bool:
        a = a.astype(np.int8)
    elif a.dtype.kind not in "iu" or a.ndim != 1 or (len(a) and (a.min() < -1 or a.max() > 1)):
        raise _fail(
            where,
            f"labels must be bool, or int with -1 unlabelled, 0 no slip, 1 slip; found dtype {a.dtype}",
            rid,
            "slip",
        )
    if a.shape != (n,):
        raise _fail(where, f"{a.shape[0] if a.ndim else 0} labels for {n} samples", rid, "slip")
    return a.astype(np.int8, copy=False)


def _check_onset(labels: np.ndarray | None, rid: str, where) -> None:
    """A hold-slip recording holds (labelled 0) and then may slip (labelled 1) from a known
    sample; a trial that held throughout (no onset) is kept: it is non-slip time."""
    if labels is None:
        raise _fail(
            where,
            "a hold-slip recording needs per-sample labels (a slip column) to give its onset",
            rid,
            "slip",
        )
    slipping = np.flatnonzero(labels == 1)
    before = labels[: slipping[0]] if len(slipping) else labels
    if not (before == 0).any():
        raise _fail(
            where,
            "a hold-slip recording has no sample labelled no-slip before its onset: no hold",
            rid,
            "slip",
        )


# ----------------------------------------------------------------------------- fingerprint
def _plain(v: Any) -> Any:
    """A metadata value as plain JSON: str, float, None, list of str."""
    if isinstance(v, tuple):
        return list(v)
    if isinstance(v, (float, np.floating)):
        return None if np.isnan(v) else float(v)
    return None if _is_null(v) else v


def content_fingerprint(
    recordings: pd.DataFrame,
    samples: Mapping[str, np.ndarray],
    slip_labels: Mapping[str, np.ndarray],
) -> str:
    """BLAKE2b (16 hex digits) of a canonical dataset's content.

    Hashes the format's columns of every recording (sorted by ``recording_id``) as JSON, then
    each recording's shape, its samples as little-endian float64 and its labels as int8 (-1 where
    a recording has none). Independent of storage: float32 values hash as their exact float64.
    """
    h = hashlib.blake2b(digest_size=8)
    meta = [
        [_plain(v) for v in row]
        for row in recordings[list(FORMAT_COLUMNS)].itertuples(index=False, name=None)
    ]
    h.update(
        json.dumps(
            {"format": FORMAT_VERSION, "columns": FORMAT_COLUMNS, "rows": meta},
            ensure_ascii=False,
            allow_nan=False,
            separators=(",", ":"),
        ).encode()
    )
    block = 1 << 18  # rows per hashed piece: a large recording is never copied whole
    for rid in recordings["recording_id"]:
        a = samples[rid]
        h.update(np.array(a.shape, "<i8").tobytes())
        for lo in range(0, len(a), block):
            h.update(np.ascontiguousarray(a[lo : lo + block], dtype="<f8").tobytes())
        labels = slip_labels.get(rid)
        h.update(
            (
                np.full(len(a), -1, np.int8)
                if labels is None
                else np.ascontiguousarray(labels, np.int8)
            ).tobytes()
        )
    return h.hexdigest()


# ----------------------------------------------------------------------------- read and write
def read_dataset(path: str | os.PathLike) -> Dataset:
    """Read and validate a dataset folder; raise :class:`DataError` naming file, recording and column.

    Rows of either file may come in any order; the result is canonical (see :class:`Dataset`).
    """
    path = Path(path)
    if not path.is_dir():
        raise DataError(
            f"{path}: not a dataset folder (expected a folder with {RECORDINGS_FILE} and {SAMPLES_FILE})"
        )
    file = path / RECORDINGS_FILE
    try:
        recordings, declared = _read_recordings(file)
        file = path / SAMPLES_FILE
        samples, labels = _read_samples(file, recordings, declared)
    except (pa.ArrowException, OSError) as exc:  # a damaged page, found while reading
        raise DataError(f"{file}: unreadable ({_one_line(exc)})") from None
    return Dataset(recordings, samples, labels, path)


def write_dataset(
    path: str | os.PathLike,
    recordings: pd.DataFrame,
    samples: Mapping[str, np.ndarray],
    slip_labels: Mapping[str, np.ndarray] | None = None,
) -> Path:
    """Validate, then write a dataset folder atomically: it appears whole or not at all.

    Parameters
    ----------
    recordings : one row per recording with the columns of ``RECORDINGS_SCHEMA``; ``trial`` is
        written when the frame has it.
    samples : recording_id -> array of shape (n_samples, n_channels). Stored as int64 when every
        array holds integers (raw counts stay exact), float32 when every array is float32, else
        float64.
    slip_labels : recording_id -> (n_samples,) bool, or int8 with -1 unlabelled (written null);
        a recording left out is unlabelled. None: no ``slip`` column.
    """
    path = Path(path)
    if path.exists() and (not path.is_dir() or any(path.iterdir())):
        raise DataError(f"{path}: already exists and is not empty; choose a new folder")
    where = f"{IN_MEMORY} to be written to {path}"
    rec, arrays, labels = _canonical(recordings, samples, slip_labels, where, where)
    ids = rec["recording_id"].tolist()
    kinds = {np.asarray(samples[r]).dtype for r in ids}
    if all(k.kind in "iu" for k in kinds):
        value_type = pa.int64()
        for rid in ids:
            if np.abs(np.asarray(samples[rid], np.float64)).max() > EXACT_INT:
                raise _fail(
                    where, "integers beyond 2**53 cannot be read back exactly", rid, "values"
                )
        arrays = {rid: np.asarray(samples[rid], np.int64) for rid in ids}
    else:
        value_type = (
            pa.float32() if all(a.dtype == np.float32 for a in arrays.values()) else pa.float64()
        )
    for rid in ids:
        if value_type != pa.int64() and not np.isfinite(arrays[rid]).all():
            raise _fail(where, "non-finite value (NaN or infinity)", rid, "values")

    meta = {VERSION_KEY: FORMAT_VERSION.encode()}
    schema = (
        RECORDINGS_SCHEMA
        if "trial" in recordings.columns
        else RECORDINGS_SCHEMA.remove(RECORDINGS_SCHEMA.get_field_index("trial"))
    )
    schema = schema.append(N_SAMPLES)
    table = {f.name: pa.array([_plain(v) for v in rec[f.name]], f.type) for f in schema}
    rec_table = pa.table(table, schema=schema).replace_schema_metadata(meta)

    parts = [arrays[r] for r in ids]
    lengths = np.array([len(a) for a in parts])
    widths = np.repeat(rec["n_channels"].to_numpy(), lengths)
    offsets = np.r_[0, np.cumsum(widths)].astype(np.int64)
    flat = np.concatenate([np.ascontiguousarray(a).ravel() for a in parts])
    columns = {
        "recording_id": pa.DictionaryArray.from_arrays(
            pa.array(np.repeat(np.arange(len(ids), dtype=np.int32), lengths)),
            pa.array(ids, pa.string()),
        ),
        "sample_index": pa.array(np.concatenate([np.arange(n, dtype=np.int64) for n in lengths])),
        "values": pa.LargeListArray.from_arrays(pa.array(offsets), pa.array(flat, value_type)),
    }
    if slip_labels:
        stacked = np.concatenate([labels[r] for r in ids])
        columns["slip"] = pa.array(stacked == 1, mask=stacked < 0)
    samples_table = pa.table(columns).replace_schema_metadata(meta)

    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    try:
        tmp.chmod(
            0o777 & ~_umask()
        )  # mkdtemp makes it 0700: a shared lab folder must stay readable
        pq.write_table(rec_table, tmp / RECORDINGS_FILE)
        pq.write_table(samples_table, tmp / SAMPLES_FILE, row_group_size=1 << 20)
        if path.exists():
            path.rmdir()
        os.replace(tmp, path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return path


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


SCENARIO_LABEL = {
    "slip": 1,
    "press": 0,
    "free-space": 0,
}  # what labelling by scenario calls each sample


def info(dataset: Dataset) -> pd.DataFrame:
    """Recordings, trials, samples and seconds per sensor, instance, scenario, material and speed;
    where the dataset has per-sample labels, the share of labelled samples that slip
    (``slip_fraction``) and the share whose label disagrees with their recording's scenario
    (``scenario_disagreement``: a slip recording's stick phases, say; NaN for hold-slip, whose
    scenario labels no sample)."""
    rec = dataset.recordings.copy()
    rec["samples"] = [len(dataset.samples[r]) for r in rec["recording_id"]]
    rec["seconds"] = rec["samples"] / rec["sampling_rate_hz"]
    aggregations = dict(
        recordings=("recording_id", "size"),
        trials=("trial", "nunique"),
        samples=("samples", "sum"),
        seconds=("seconds", "sum"),
    )
    if dataset.slip_labels:
        labels = [dataset.slip_labels[r] for r in rec["recording_id"]]
        rec["labelled"] = [int((lab >= 0).sum()) for lab in labels]
        rec["slipping"] = [int((lab == 1).sum()) for lab in labels]
        rec["disagreeing"] = [
            int(((lab >= 0) & (lab != SCENARIO_LABEL[sc])).sum())
            if sc in SCENARIO_LABEL
            else np.nan
            for lab, sc in zip(labels, rec["scenario"])
        ]
        aggregations |= dict(
            labelled=("labelled", "sum"),
            slipping=("slipping", "sum"),
            disagreeing=("disagreeing", lambda v: v.sum(min_count=1)),
        )
    keys = ["sensor_type", "sensor_instance", "scenario", "material", "speed_mm_s"]
    table = rec.groupby(keys, dropna=False, sort=True).agg(**aggregations).reset_index()
    if dataset.slip_labels:
        table["slip_fraction"] = table["slipping"] / table["labelled"].where(table["labelled"] > 0)
        table["scenario_disagreement"] = table["disagreeing"] / table["labelled"].where(
            table["labelled"] > 0
        )
        table = table.drop(columns=["labelled", "slipping", "disagreeing"])
    return table
