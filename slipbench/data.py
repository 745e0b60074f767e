"""The Parquet dataset format, version 1: reading, validating and writing.

A dataset is a folder holding two Parquet files (see ``datasets.md``):

``recordings.parquet``
    one row per recording: ``recording_id``, ``sensor_type``, ``sensor_instance``,
    ``scenario`` (``slip``, ``press`` or ``free-space``), ``material``, ``speed_mm_s``,
    ``sampling_rate_hz``, ``channels``, ``units``, ``source``.
``samples.parquet``
    one row per sample: ``recording_id``, ``sample_index`` (0, 1, ... in order, the rows of one
    recording contiguous), ``values`` (one float per channel) and optionally ``slip`` (bool).

Both files carry ``slipbench.format_version = "1"`` in their schema metadata.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from .errors import DataError

FORMAT_VERSION = "1"
VERSION_KEY = b"slipbench.format_version"
RECORDINGS_FILE = "recordings.parquet"
SAMPLES_FILE = "samples.parquet"
SCENARIOS = ("slip", "press", "free-space")

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
    ]
)
# Columns that may hold nulls: free-space has no material, pressing has no speed.
NULLABLE = {"material", "speed_mm_s", "source"}


@dataclass
class Dataset:
    """Recordings metadata plus each recording's samples, validated.

    Attributes
    ----------
    recordings : DataFrame, one row per recording, in file order.
    samples : dict recording_id -> float32 array of shape (n_samples, n_channels).
    slip_labels : dict recording_id -> bool array of shape (n_samples,), only where the file has them.
    path : where the dataset was read from (None if built in memory).
    """

    recordings: pd.DataFrame
    samples: dict[str, np.ndarray]
    slip_labels: dict[str, np.ndarray] = field(default_factory=dict)
    path: Path | None = None
    fingerprint: str = ""

    def sensors(self) -> list[tuple[str, str]]:
        """(sensor_type, sensor_instance) pairs in order of first appearance."""
        return sensor_pairs(self.recordings)


def sensor_pairs(recordings: pd.DataFrame) -> list[tuple[str, str]]:
    """(sensor_type, sensor_instance) pairs of a recordings table, in order of first appearance."""
    pairs = recordings[["sensor_type", "sensor_instance"]].drop_duplicates()
    return list(pairs.itertuples(index=False, name=None))


def _fail(file: Path, what: str, recording: str | None = None, column: str | None = None) -> DataError:
    where = [str(file)]
    if recording is not None:
        where.append(f"recording {recording!r}")
    if column is not None:
        where.append(f"column {column!r}")
    return DataError(f"{': '.join(where)}: {what}")


def _open_parquet(file: Path) -> pq.ParquetFile:
    """Open a Parquet file of the format, checking its version; columns are read one by one
    later so that reading a large dataset never holds every column at once."""
    if not file.is_file():
        raise DataError(f"{file}: missing (a slipbench dataset folder holds {RECORDINGS_FILE} and {SAMPLES_FILE})")
    try:
        pf = pq.ParquetFile(file)
        schema = pf.schema_arrow
    except (pa.ArrowException, OSError) as exc:
        raise DataError(f"{file}: not a readable Parquet file ({exc})") from None
    version = (schema.metadata or {}).get(VERSION_KEY)
    if version is None:
        raise _fail(file, f"no {VERSION_KEY.decode()} in the schema metadata; is this a slipbench dataset?")
    if version.decode() != FORMAT_VERSION:
        raise _fail(file, f"format version {version.decode()!r} is not supported (this slipbench reads {FORMAT_VERSION!r})")
    return pf


def _check_type(pf: pq.ParquetFile, file: Path, name: str, type_check, type_name: str) -> None:
    names = pf.schema_arrow.names
    if name not in names:
        raise _fail(file, f"required column missing (columns present: {', '.join(names)})", column=name)
    if not type_check(pf.schema_arrow.field(name).type):
        raise _fail(file, f"must be {type_name}, found {pf.schema_arrow.field(name).type}", column=name)


def _column(pf: pq.ParquetFile, file: Path, name: str, type_check, type_name: str) -> pa.Array:
    _check_type(pf, file, name, type_check, type_name)
    return pf.read(columns=[name]).column(name).combine_chunks()


def _chunks(pf: pq.ParquetFile, name: str):
    """(first row, array) for each chunk of a column, one row group at a time."""
    row0 = 0
    for group in range(pf.num_row_groups):
        for chunk in pf.read_row_group(group, columns=[name]).column(name).chunks:
            yield row0, chunk
            row0 += len(chunk)


def _first_bad(ids: np.ndarray, mask: np.ndarray) -> str:
    return str(ids[np.flatnonzero(mask)[0]])


def _read_recordings(file: Path) -> pd.DataFrame:
    table = _open_parquet(file).read()
    checks = {
        "recording_id": (pa.types.is_string, "string"),
        "sensor_type": (pa.types.is_string, "string"),
        "sensor_instance": (pa.types.is_string, "string"),
        "scenario": (pa.types.is_string, "string"),
        "material": (lambda t: pa.types.is_string(t) or pa.types.is_null(t), "string"),
        "speed_mm_s": (lambda t: pa.types.is_floating(t) or pa.types.is_integer(t) or pa.types.is_null(t), "a number"),
        "sampling_rate_hz": (lambda t: pa.types.is_floating(t) or pa.types.is_integer(t), "a number"),
        "channels": (lambda t: pa.types.is_list(t) and pa.types.is_string(t.value_type), "a list of strings"),
        "units": (lambda t: pa.types.is_list(t) and pa.types.is_string(t.value_type), "a list of strings"),
        "source": (lambda t: pa.types.is_string(t) or pa.types.is_null(t), "string"),
    }
    for name, (check, type_name) in checks.items():
        if name not in table.column_names:
            raise _fail(file, f"required column missing (columns present: {', '.join(table.column_names)})", column=name)
        if not check(table.column(name).type):
            raise _fail(file, f"must be {type_name}, found {table.column(name).type}", column=name)
    df = table.select(list(checks)).to_pandas()
    ids = df["recording_id"].to_numpy(dtype=object)
    for name in checks:
        if name not in NULLABLE and df[name].isna().any():
            bad = df[name].isna().to_numpy()
            raise _fail(file, "null value", _first_bad(ids, bad) if name != "recording_id" else None, name)
    dup = df["recording_id"].duplicated().to_numpy()
    if dup.any():
        raise _fail(file, "recording_id is not unique", _first_bad(ids, dup), "recording_id")
    bad = ~df["scenario"].isin(SCENARIOS).to_numpy()
    if bad.any():
        value = df["scenario"].to_numpy()[bad][0]
        raise _fail(file, f"scenario {value!r} is not one of {', '.join(SCENARIOS)}", _first_bad(ids, bad), "scenario")
    rate = df["sampling_rate_hz"].to_numpy(dtype=float)
    bad = ~(np.isfinite(rate) & (rate > 0))
    if bad.any():
        raise _fail(file, f"sampling rate must be a finite positive number, got {rate[bad][0]}", _first_bad(ids, bad), "sampling_rate_hz")
    speed = df["speed_mm_s"].to_numpy(dtype=float, na_value=np.nan)
    bad = ~np.isnan(speed) & ~(np.isfinite(speed) & (speed >= 0))
    if bad.any():
        raise _fail(file, f"speed must be finite and >= 0, got {speed[bad][0]}", _first_bad(ids, bad), "speed_mm_s")
    n_ch = df["channels"].map(len).to_numpy()
    bad = n_ch == 0
    if bad.any():
        raise _fail(file, "no channels", _first_bad(ids, bad), "channels")
    bad = df["units"].map(len).to_numpy() != n_ch
    if bad.any():
        raise _fail(file, "units must list one unit per channel", _first_bad(ids, bad), "units")
    df["speed_mm_s"] = speed
    df["sampling_rate_hz"] = rate
    df["channels"] = df["channels"].map(tuple)
    df["units"] = df["units"].map(tuple)
    df["n_channels"] = n_ch
    return df


def _read_samples(file: Path, recordings: pd.DataFrame) -> tuple[dict, dict]:
    pf = _open_parquet(file)
    ids = recordings["recording_id"].to_numpy(dtype=object)
    n_rows = pf.metadata.num_rows
    if n_rows == 0:
        raise _fail(file, "no samples")

    # 1. recording ids -> contiguous runs, one per recording
    rid = _column(pf, file, "recording_id", lambda t: pa.types.is_string(t) or (pa.types.is_dictionary(t) and pa.types.is_string(t.value_type)), "string")
    if rid.null_count:
        raise _fail(file, "null value", column="recording_id")
    encoded = rid if pa.types.is_dictionary(rid.type) else pc.dictionary_encode(rid)
    del rid
    dict_ids = encoded.dictionary.to_numpy(zero_copy_only=False)
    lookup = pd.Index(ids).get_indexer(dict_ids).astype(np.int32)
    if (lookup < 0).any():
        raise _fail(file, "recording not listed in recordings.parquet", str(dict_ids[lookup < 0][0]), "recording_id")
    codes = lookup[encoded.indices.to_numpy()]
    del encoded
    starts = np.flatnonzero(np.r_[True, codes[1:] != codes[:-1]])
    run_codes = codes[starts]
    del codes
    if len(np.unique(run_codes)) != len(run_codes):
        dup = run_codes[pd.Series(run_codes).duplicated().to_numpy()][0]
        raise _fail(file, "samples of this recording are not in one contiguous block", ids[dup], "recording_id")
    missing = np.setdiff1d(np.arange(len(ids)), run_codes)
    if len(missing):
        raise _fail(file, "recording has no samples", ids[missing[0]], "recording_id")
    lengths = np.diff(np.r_[starts, n_rows])
    if (lengths < 2).any():
        raise _fail(file, "a recording needs at least 2 samples", ids[run_codes[lengths < 2][0]], "sample_index")

    def where(row: int) -> str:
        return ids[run_codes[np.searchsorted(starts, row, side="right") - 1]]

    # 2. sample indices: each row's index is its distance from its run's start. Read one row
    # group at a time, so that a large dataset never holds a whole column of int64 at once.
    _check_type(pf, file, "sample_index", pa.types.is_integer, "an integer")
    def run_of(rows: np.ndarray) -> np.ndarray:
        return np.searchsorted(starts, rows, side="right") - 1

    for row0, chunk in _chunks(pf, "sample_index"):
        if chunk.null_count:
            raise _fail(file, "null value", column="sample_index")
        got = chunk.to_numpy()
        rows = np.arange(row0, row0 + len(got))
        expected = rows - starts[run_of(rows)]
        bad = got != expected
        if bad.any():
            i = int(np.argmax(bad))
            raise _fail(file, f"sample_index must run 0, 1, 2, ... in order; row {rows[i]} has {got[i]}, expected {expected[i]}",
                        where(int(rows[i])), "sample_index")

    # 3. values: one per channel, finite; copied row group by row group into one float32 array
    _check_type(
        pf, file, "values",
        lambda t: (pa.types.is_list(t) or pa.types.is_large_list(t) or pa.types.is_fixed_size_list(t)) and pa.types.is_floating(t.value_type),
        "a list of floats",
    )
    n_ch = recordings["n_channels"].to_numpy()[run_codes]
    flat = np.empty(int((n_ch * lengths).sum()), np.float32)
    pos = 0
    for row0, chunk in _chunks(pf, "values"):
        if chunk.null_count:
            raise _fail(file, "null list of values", where(row0 + int(np.argmax(chunk.is_null().to_numpy(zero_copy_only=False)))), "values")
        if pa.types.is_fixed_size_list(chunk.type):
            widths = np.full(len(chunk), chunk.type.list_size)
        else:
            widths = np.diff(chunk.offsets.to_numpy())
        channels = n_ch[run_of(np.arange(row0, row0 + len(chunk)))]
        bad = widths != channels
        if bad.any():
            i = int(np.argmax(bad))
            raise _fail(file, f"row {row0 + i} has {widths[i]} values but the recording has {channels[i]} channels",
                        where(row0 + i), "values")
        part = chunk.flatten()
        if part.null_count:
            raise _fail(file, "null channel value", column="values")
        part = part.to_numpy().astype(np.float32, copy=False)
        finite = np.isfinite(part)
        if not finite.all():
            row = row0 + int(np.searchsorted(np.cumsum(widths), int(np.argmin(finite)), side="right"))
            raise _fail(file, f"non-finite value (NaN or infinity) at sample_index {row - starts[run_of(row)]}", where(row), "values")
        flat[pos : pos + len(part)] = part
        pos += len(part)
    offsets = np.r_[0, np.cumsum(n_ch * lengths)]

    labels_all = None
    if "slip" in pf.schema_arrow.names:
        labels_all = _column(pf, file, "slip", pa.types.is_boolean, "bool")
        if labels_all.null_count:
            raise _fail(file, "null value", column="slip")
        labels_all = labels_all.to_numpy(zero_copy_only=False)

    samples: dict[str, np.ndarray] = {}
    labels: dict[str, np.ndarray] = {}
    for run, (code, start, length, channels) in enumerate(zip(run_codes, starts, lengths, n_ch)):
        rid_ = ids[code]
        lo = offsets[run]
        samples[rid_] = flat[lo : lo + length * channels].reshape(length, channels)
        if labels_all is not None:
            labels[rid_] = labels_all[start : start + length]
    return samples, labels


def fingerprint(path: Path) -> str:
    """Content hash of a dataset folder's two files (first 16 hex digits of BLAKE2b)."""
    h = hashlib.blake2b(digest_size=8)
    for name in (RECORDINGS_FILE, SAMPLES_FILE):
        with open(Path(path) / name, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 22), b""):
                h.update(block)
    return h.hexdigest()


def read_dataset(path: str | os.PathLike) -> Dataset:
    """Read and validate a dataset folder; raise :class:`DataError` naming file, recording and column."""
    path = Path(path)
    if not path.is_dir():
        raise DataError(f"{path}: not a dataset folder (expected a folder with {RECORDINGS_FILE} and {SAMPLES_FILE})")
    recordings = _read_recordings(path / RECORDINGS_FILE)
    samples, labels = _read_samples(path / SAMPLES_FILE, recordings)
    return Dataset(recordings, samples, labels, path, fingerprint(path))


def write_dataset(
    path: str | os.PathLike,
    recordings: pd.DataFrame,
    samples: Mapping[str, np.ndarray],
    slip_labels: Mapping[str, np.ndarray] | None = None,
) -> Path:
    """Write a dataset folder atomically: it appears whole or not at all.

    Parameters
    ----------
    recordings : one row per recording with the columns of ``RECORDINGS_SCHEMA``.
    samples : recording_id -> array of shape (n_samples, n_channels).
    slip_labels : recording_id -> bool array (n_samples,); give it for all recordings or none.
    """
    path = Path(path)
    if path.exists() and any(path.iterdir()):
        raise DataError(f"{path}: already exists and is not empty; choose a new folder")
    rec = recordings[[f.name for f in RECORDINGS_SCHEMA]].copy()
    rec["channels"] = rec["channels"].map(list)
    rec["units"] = rec["units"].map(list)
    meta = {VERSION_KEY: FORMAT_VERSION.encode()}
    rec_table = pa.Table.from_pandas(rec, schema=RECORDINGS_SCHEMA, preserve_index=False).replace_schema_metadata(meta)

    ids = list(rec["recording_id"])
    arrays = [np.asarray(samples[r], dtype=np.float32) for r in ids]
    lengths = np.array([len(a) for a in arrays])
    widths = np.repeat([a.shape[1] for a in arrays], lengths)
    offsets = np.r_[0, np.cumsum(widths)].astype(np.int64)
    values = pa.LargeListArray.from_arrays(pa.array(offsets), pa.array(np.concatenate([a.ravel() for a in arrays])))
    columns = {
        "recording_id": pa.DictionaryArray.from_arrays(
            pa.array(np.repeat(np.arange(len(ids), dtype=np.int32), lengths)), pa.array(ids, pa.string())
        ),
        "sample_index": pa.array(np.concatenate([np.arange(n, dtype=np.int64) for n in lengths])),
        "values": values,
    }
    if slip_labels is not None:
        columns["slip"] = pa.array(np.concatenate([np.asarray(slip_labels[r], dtype=bool) for r in ids]))
    samples_table = pa.table(columns).replace_schema_metadata(meta)

    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    try:
        pq.write_table(rec_table, tmp / RECORDINGS_FILE)
        pq.write_table(samples_table, tmp / SAMPLES_FILE, row_group_size=1 << 20)
        if path.exists():
            path.rmdir()
        os.replace(tmp, path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return path


def info(dataset: Dataset) -> pd.DataFrame:
    """Recordings, samples and seconds per sensor, instance, scenario, material and speed."""
    rec = dataset.recordings.copy()
    rec["samples"] = [len(dataset.samples[r]) for r in rec["recording_id"]]
    rec["seconds"] = rec["samples"] / rec["sampling_rate_hz"]
    keys = ["sensor_type", "sensor_instance", "scenario", "material", "speed_mm_s"]
    table = (
        rec.groupby(keys, dropna=False, sort=True)
        .agg(recordings=("recording_id", "size"), samples=("samples", "sum"), seconds=("seconds", "sum"))
        .reset_index()
    )
    return table
