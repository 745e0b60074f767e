"""Writing a dataset folder: validated to the canonical form first, then written atomically
(the folder appears whole or not at all), in the smallest value type that holds every sample
exactly."""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from slipbench.atomic import open_parquet
from slipbench.data.canonical import canonical_dataset, names_univariate_channels, plain_value
from slipbench.data.fingerprint import content_fingerprint, recordings_digest
from slipbench.data.messages import data_error
from slipbench.data.schema import (
    EXACT_INT,
    FINGERPRINT_KEY,
    FORMAT_KEYS,
    FORMAT_VERSION,
    IN_MEMORY,
    N_SAMPLES,
    RECORDINGS_DIGEST_KEY,
    RECORDINGS_FILE,
    RECORDINGS_SCHEMA,
    SAMPLES_FILE,
    UNIVARIATE_CHANNELS,
    VERSION_KEY,
)
from slipbench.errors import DataError, writing


def write_dataset(
    path: str | os.PathLike,
    recordings: pd.DataFrame,
    samples: Mapping[str, np.ndarray],
    slip_labels: Mapping[str, np.ndarray] | None = None,
    description: Mapping[bytes, str] | None = None,
) -> Path:
    """Validate, then write a dataset folder atomically: it appears whole or not at all.

    Every page carries a CRC checksum, and both files the content fingerprint (recordings.parquet
    also a digest of its table): the readers verify both, so a damaged file is refused, not read.

    Parameters
    ----------
    recordings : one row per recording with the columns of ``RECORDINGS_SCHEMA``; ``trial`` is
        written when the frame has it, ``univariate_channels`` when a recording names any.
    samples : recording_id -> array of shape (n_samples, n_channels). Stored as int64 when every
        array holds integers (raw counts stay exact), float32 when every array is float32, else
        float64.
    slip_labels : recording_id -> (n_samples,) bool, or int8 with -1 unlabelled (written null);
        a recording left out is unlabelled. None: no ``slip`` column.
    description : more keys for recordings.parquet's schema metadata, e.g. ``SOURCE_KEY`` and
        ``CITATION_KEY`` (:func:`slipbench.data.read.read_description` reads them back). They are
        not part of the content fingerprint; the format's own keys cannot be set this way.
    """
    path = Path(path)
    description = dict(description or {})
    owned = sorted(k.decode() for k in description if k in FORMAT_KEYS)
    if owned:
        raise DataError(
            f"{path}: the format writes {', '.join(owned)} itself; describe with other keys"
        )
    if path.exists() and (not path.is_dir() or any(path.iterdir())):
        raise DataError(f"{path}: already exists and is not empty; choose a new folder")
    where = f"{IN_MEMORY} to be written to {path}"
    rec, arrays, labels = canonical_dataset(recordings, samples, slip_labels, where, where)
    ids = rec["recording_id"].tolist()
    kinds = {np.asarray(samples[r]).dtype for r in ids}
    if all(k.kind in "iu" for k in kinds):
        value_type = pa.int64()
        for rid in ids:
            if np.abs(np.asarray(samples[rid], np.float64)).max() > EXACT_INT:
                raise data_error(
                    where, "integers beyond 2**53 cannot be read back exactly", rid, "values"
                )
        arrays = {rid: np.asarray(samples[rid], np.int64) for rid in ids}
    else:
        value_type = (
            pa.float32() if all(a.dtype == np.float32 for a in arrays.values()) else pa.float64()
        )
    for rid in ids:
        if value_type != pa.int64() and not np.isfinite(arrays[rid]).all():
            raise data_error(where, "non-finite value (NaN or infinity)", rid, "values")

    # the readers check pages against their checksums and the content against these
    fingerprint = content_fingerprint(rec, arrays, labels).encode()
    meta = {VERSION_KEY: FORMAT_VERSION.encode(), FINGERPRINT_KEY: fingerprint}
    schema = (
        RECORDINGS_SCHEMA
        if "trial" in recordings.columns
        else RECORDINGS_SCHEMA.remove(RECORDINGS_SCHEMA.get_field_index("trial"))
    )
    if names_univariate_channels(rec):
        schema = schema.append(UNIVARIATE_CHANNELS)
    schema = schema.append(N_SAMPLES)
    table = {f.name: pa.array([plain_value(v) for v in rec[f.name]], f.type) for f in schema}
    rec_table = pa.table(table, schema=schema).replace_schema_metadata(
        {
            **{k: v.encode() for k, v in description.items()},
            **meta,
            RECORDINGS_DIGEST_KEY: recordings_digest(rec).encode(),
        }
    )

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

    # pyarrow's OSErrors name no file: each step names what it writes (never the hidden folder)
    with writing(path, "create the folder"):
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    try:
        with writing(path, "create the folder"):
            tmp.chmod(0o777 & ~_umask())  # mkdtemp's 0700 would hide a shared lab folder
        with writing(path / RECORDINGS_FILE):
            pq.write_table(rec_table, tmp / RECORDINGS_FILE, write_page_checksum=True)
        with writing(path / SAMPLES_FILE):
            pq.write_table(
                samples_table, tmp / SAMPLES_FILE, row_group_size=1 << 20, write_page_checksum=True
            )
        with writing(path):
            if path.exists():
                path.rmdir()
            os.replace(tmp, path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return path


def rewrite_dataset(src: str | os.PathLike, out: str | os.PathLike) -> Path:
    """Write the dataset at ``src`` to the new folder ``out`` as :func:`write_dataset` writes:
    page checksums and the stored fingerprint, which a file from another tool may lack.

    The content is the same (so is the fingerprint), integers stay integers, and the source
    and citation ``dataset fetch`` recorded are kept. ``src`` is read whole and validated first.
    """
    from slipbench.data.read import read_dataset, read_description

    ds = read_dataset(src)
    values = open_parquet(Path(src) / SAMPLES_FILE).schema_arrow.field("values").type
    samples = (
        {rid: a.astype(np.int64) for rid, a in ds.samples.items()}  # read as exact float64
        if pa.types.is_integer(values.value_type)
        else ds.samples
    )
    description = {k.encode(): v for k, v in read_description(src).items()}
    return write_dataset(out, ds.recordings, samples, ds.slip_labels or None, description)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask
