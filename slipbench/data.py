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


def _read_parquet(file: Path) -> pa.Table:
    if not file.is_file():
        raise DataError(f"{file}: missing (a slipbench dataset folder holds {RECORDINGS_FILE} and {SAMPLES_FILE})")
    try:
        table = pq.read_table(file)
    except (pa.ArrowException, OSError) as exc:
        raise DataError(f"{file}: not a readable Parquet file ({exc})") from None
    version = (table.schema.metadata or {}).get(VERSION_KEY)
    if version is None:
        raise _fail(file, f"no {VERSION_KEY.decode()} in the schema metadata; is this a slipbench dataset?")
    if version.decode() != FORMAT_VERSION:
        raise _fail(file, f"format version {version.decode()!r} is not supported (this slipbench reads {FORMAT_VERSION!r})")
    return table


def _require(table: pa.Table, file: Path, name: str, type_check, type_name: str) -> pa.ChunkedArray:
    if name not in table.column_names:
        raise _fail(file, f"required column missing (columns present: {', '.join(table.column_names)})", column=name)
    col = table.column(name)
    if not type_check(col.type):
        raise _fail(file, f"must be {type_name}, found {col.type}", column=name)
    return col


def _first_bad(ids: np.ndarray, mask: np.ndarray) -> str:
    return str(ids[np.flatnonzero(mask)[0]])


def _read_recordings(file: Path) -> pd.DataFrame:
    table = _read_parquet(file)
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
        _require(table, file, name, check, type_name)
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
    table = _read_parquet(file)
    rid_col = _require(table, file, "recording_id", lambda t: pa.types.is_string(t) or (pa.types.is_dictionary(t) and pa.types.is_string(t.value_type)), "string")
    idx_col = _require(table, file, "sample_index", pa.types.is_integer, "an integer")
    val_col = _require(
        table, file, "values",
        lambda t: (pa.types.is_list(t) or pa.types.is_large_list(t) or pa.types.is_fixed_size_list(t)) and pa.types.is_floating(t.value_type),
        "a list of floats",
    )
    ids = recordings["recording_id"].to_numpy(dtype=object)
    n_rows = table.num_rows
    if n_rows == 0:
        raise _fail(file, "no samples")
    # Map each row's recording id to its row in recordings.parquet, via a dictionary encoding.
    encoded = pc.dictionary_encode(rid_col.combine_chunks() if isinstance(rid_col, pa.ChunkedArray) else rid_col)
    if encoded.null_count:
        raise _fail(file, "null value", column="recording_id")
    dict_ids = encoded.dictionary.to_numpy(zero_copy_only=False)
    lookup = pd.Index(ids).get_indexer(dict_ids)
    if (lookup < 0).any():
        raise _fail(file, "recording not listed in recordings.parquet", str(dict_ids[lookup < 0][0]), "recording_id")
    codes = lookup[encoded.indices.to_numpy()]
    starts = np.flatnonzero(np.r_[True, codes[1:] != codes[:-1]])
    run_codes = codes[starts]
    if len(np.unique(run_codes)) != len(run_codes):
        dup = run_codes[pd.Series(run_codes).duplicated().to_numpy()][0]
        raise _fail(file, "samples of this recording are not in one contiguous block", ids[dup], "recording_id")
    missing = np.setdiff1d(np.arange(len(ids)), run_codes)
    if len(missing):
        raise _fail(file, "recording has no samples", ids[missing[0]], "recording_id")
    ends = np.r_[starts[1:], n_rows]
    lengths = ends - starts
    if (lengths < 2).any():
        raise _fail(file, "a recording needs at least 2 samples", ids[run_codes[lengths < 2][0]], "sample_index")

    if idx_col.null_count:
        raise _fail(file, "null value", column="sample_index")
    sample_index = idx_col.to_numpy()
    expected = np.arange(n_rows) - np.repeat(starts, lengths)
    bad = sample_index != expected
    if bad.any():
        row = np.flatnonzero(bad)[0]
        raise _fail(
            file, f"sample_index must run 0, 1, 2, ... in order; row {row} has {sample_index[row]}, expected {expected[row]}",
            ids[codes[row]], "sample_index",
        )

    values = val_col.combine_chunks()
    if values.null_count:
        raise _fail(file, "null list of values", ids[codes[np.flatnonzero(values.is_null().to_numpy(zero_copy_only=False))[0]]], "values")
    if pa.types.is_fixed_size_list(values.type):
        widths = np.full(n_rows, values.type.list_size)
    else:
        widths = np.diff(values.offsets.to_numpy())
    n_ch = recordings["n_channels"].to_numpy()[codes]
    bad = widths != n_ch
    if bad.any():
        row = np.flatnonzero(bad)[0]
        raise _fail(file, f"row {row} has {widths[row]} values but the recording has {n_ch[row]} channels", ids[codes[row]], "values")
    flat = values.flatten()
    if flat.null_count:
        raise _fail(file, "null channel value", column="values")
    flat = flat.to_numpy().astype(np.float32, copy=False)
    finite = np.isfinite(flat)
    if not finite.all():
        row = np.searchsorted(np.cumsum(widths), np.flatnonzero(~finite)[0], side="right")
        raise _fail(file, f"non-finite value (NaN or infinity) at sample_index {sample_index[row]}", ids[codes[row]], "values")

    labels_col = table.column("slip") if "slip" in table.column_names else None
    if labels_col is not None:
        if not pa.types.is_boolean(labels_col.type):
            raise _fail(file, f"must be bool, found {labels_col.type}", column="slip")
        if labels_col.null_count:
            raise _fail(file, "null value", column="slip")
        labels_all = labels_col.to_numpy()

    samples: dict[str, np.ndarray] = {}
    labels: dict[str, np.ndarray] = {}
    value_starts = np.r_[0, np.cumsum(widths)]
    for code, start, length in zip(run_codes, starts, lengths):
        rid = ids[code]
        lo, hi = value_starts[start], value_starts[start + length]
        samples[rid] = flat[lo:hi].reshape(length, n_ch[start])
        if labels_col is not None:
            labels[rid] = labels_all[start : start + length]
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
