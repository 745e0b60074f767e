"""The content fingerprint of a canonical dataset: the same recordings give the same 16 hex
digits however they were stored (row order, Arrow flavours, pyarrow version) or built in memory."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping

import numpy as np
import pandas as pd

from slipbench.data.canonical import names_univariate_channels, plain_value
from slipbench.data.schema import FORMAT_COLUMNS, FORMAT_VERSION, UNIVARIATE_CHANNELS


def content_fingerprint(
    recordings: pd.DataFrame,
    samples: Mapping[str, np.ndarray],
    slip_labels: Mapping[str, np.ndarray],
) -> str:
    """BLAKE2b (16 hex digits) of a canonical dataset's content.

    Hashes the format's columns of every recording (sorted by ``recording_id``) as JSON (with
    ``univariate_channels`` where a recording names any: without, a dataset hashes as before), then
    each recording's shape, its samples as little-endian float64 and its labels as int8 (-1 where
    a recording has none). Independent of storage: float32 values hash as their exact float64.
    """
    h = hashlib.blake2b(digest_size=8)
    h.update(_metadata_json(recordings))
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


def recordings_digest(recordings: pd.DataFrame) -> str:
    """BLAKE2b (16 hex digits) of the format's columns of every recording (sorted by
    ``recording_id``): what ``recordings.parquet`` holds, so that a change of it is told apart
    from a change of the samples."""
    return hashlib.blake2b(_metadata_json(recordings), digest_size=8).hexdigest()


def _metadata_json(recordings: pd.DataFrame) -> bytes:
    columns = FORMAT_COLUMNS + (
        (UNIVARIATE_CHANNELS.name,) if names_univariate_channels(recordings) else ()
    )
    meta = [
        [plain_value(v) for v in row]
        for row in recordings[list(columns)].itertuples(index=False, name=None)
    ]
    return json.dumps(
        {"format": FORMAT_VERSION, "columns": columns, "rows": meta},
        ensure_ascii=False,
        allow_nan=False,
        separators=(",", ":"),
    ).encode()
