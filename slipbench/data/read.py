"""Reading and validating a dataset folder (the format of :mod:`slipbench.data.schema`).

The reader takes every Arrow flavour of strings (string, large_string, string_view, dictionary)
and lists (list, large_list, fixed_size_list) that pandas, pyarrow and Polars write, and gives
the same :class:`~slipbench.data.format.Dataset`, with the same fingerprint, whatever the row
order of either file. A wrong file raises :class:`DataError` naming file, recording and column;
the samples file is read one row group at a time, so a large dataset never sits in memory whole.

A damaged file is refused, naming it: pages are checked against their CRC checksums where the
writer stored them, and the content against the fingerprint (and the recordings table against
its digest) stored in the files' metadata. Datasets written without them still read.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from slipbench.atomic import open_parquet
from slipbench.data.canonical import canonical_recordings
from slipbench.data.fingerprint import recordings_digest
from slipbench.data.format import Dataset
from slipbench.data.messages import data_error, one_line
from slipbench.data.schema import (
    EXACT_INT,
    FINGERPRINT_KEY,
    FORMAT_KEYS,
    FORMAT_VERSION,
    OPTIONAL,
    RECORDINGS_DIGEST_KEY,
    RECORDINGS_FILE,
    SAMPLES_FILE,
    VERSION_KEY,
)
from slipbench.errors import DataError
from slipbench.vocabulary import SENSOR_TYPE, SLIPS


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
        recordings, declared, rec_meta = _read_recordings(file)
        file = path / SAMPLES_FILE
        samples, labels, samples_meta = _read_samples(file, recordings, declared)
    except (pa.ArrowException, OSError) as exc:  # a damaged page, found while reading
        raise DataError(f"{file}: unreadable ({one_line(exc)})") from None
    ds = Dataset(recordings, samples, labels, path)
    _verify(ds, path, rec_meta, samples_meta)
    return ds


def stored_fingerprint(path: str | os.PathLike) -> str:
    """The content fingerprint slipbench stored in a dataset folder's recordings.parquet when
    it wrote it ("" where there is none, or no such file): reads the schema only."""
    try:
        meta = open_parquet(Path(path) / RECORDINGS_FILE).schema_arrow.metadata or {}
    except (pa.ArrowException, OSError):
        return ""
    return meta.get(FINGERPRINT_KEY, b"").decode()


def read_recordings(path: str | os.PathLike) -> tuple[pd.DataFrame, str] | None:
    """A dataset folder's canonical recordings (``n_samples`` as recordings.parquet declares
    them) and the fingerprint its writer stored, read without the samples: what a run needs to
    find its cells in a results folder (:func:`slipbench.engine.cached.cached_rows`). The
    recordings are checked against their stored digest; the samples are not read, so they are
    checked against the fingerprint when a run reads them (:func:`read_dataset`). None where
    the folder stores no fingerprint, or not the same one in both files, or no length for
    every recording: then only :func:`read_dataset` can say what the content is."""
    path = Path(path)
    if not path.is_dir():
        return None
    file = path / RECORDINGS_FILE
    try:
        recordings, declared, rec_meta = _read_recordings(file)
        file = path / SAMPLES_FILE
        samples_meta = _open_parquet(file).schema_arrow.metadata or {}
    except (pa.ArrowException, OSError) as exc:
        raise DataError(f"{file}: unreadable ({one_line(exc)})") from None
    _verify_recordings(recordings, path, rec_meta)
    stored = {meta.get(FINGERPRINT_KEY) for meta in (rec_meta, samples_meta)}
    fingerprint = stored.pop() if len(stored) == 1 else None
    ids = recordings["recording_id"]
    if fingerprint is None or not ids.isin(list(declared)).all():
        return None
    recordings["n_samples"] = ids.map(declared).to_numpy(np.int64)
    recordings[SLIPS] = _slipping(file, recordings)
    return recordings, fingerprint.decode(errors="replace")


def _slipping(file: Path, recordings: pd.DataFrame) -> np.ndarray:
    """(n_recordings,) bool: which recordings slip at all (the canonical reader's ``slips``),
    from the samples file's ``slip`` labels alone: a protocol's cells depend on it."""
    slipping = recordings["scenario"].eq("slip").to_numpy()
    if "slip" not in _open_parquet(file).schema_arrow.names:
        return slipping
    try:
        labels = pq.read_table(file, columns=["recording_id", "slip"])
    except (pa.ArrowException, OSError) as exc:
        raise DataError(f"{file}: unreadable ({one_line(exc)})") from None
    slips = labels["slip"].to_numpy(zero_copy_only=False) == 1  # bool or integer labels
    slipped = set(labels["recording_id"].to_numpy(zero_copy_only=False)[slips])
    return slipping | recordings["recording_id"].isin(slipped).to_numpy()


def read_description(path: str | os.PathLike) -> dict[str, str]:
    """What a dataset folder says about itself beyond its content: the keys of recordings.parquet's
    schema metadata other than the format's own (``slipbench.source``, ``slipbench.citation``
    where ``dataset fetch`` wrote them), as text. Reads the schema only; call
    :func:`read_dataset` to validate the folder."""
    file = Path(path) / RECORDINGS_FILE
    try:
        meta = open_parquet(file).schema_arrow.metadata or {}
    except (pa.ArrowException, OSError) as exc:
        raise DataError(f"{file}: unreadable ({one_line(exc)})") from None
    return {
        k.decode(errors="replace"): v.decode(errors="replace")
        for k, v in meta.items()
        if k.startswith(b"slipbench.") and k not in FORMAT_KEYS
    }


AFTER = "the file is damaged, or was changed after slipbench wrote it"


def _verify_recordings(recordings: pd.DataFrame, path: Path, rec_meta: Mapping) -> None:
    """The recordings against the digest their writer stored (where it did)."""
    stored = rec_meta.get(RECORDINGS_DIGEST_KEY)
    if stored is not None:
        now = recordings_digest(recordings)
        if stored.decode(errors="replace") != now:
            raise data_error(
                path / RECORDINGS_FILE,
                f"its recordings give digest {now}, not the {stored.decode(errors='replace')} "
                f"stored when it was written: {AFTER}",
            )


def _verify(ds: Dataset, path: Path, rec_meta: Mapping, samples_meta: Mapping) -> None:
    """Compare the content with what the writer stored (where it did): the recordings digest
    first, so that a change in recordings.parquet is not blamed on samples.parquet."""
    _verify_recordings(ds.recordings, path, rec_meta)
    stored = {
        name: meta[FINGERPRINT_KEY].decode(errors="replace")
        for name, meta in ((RECORDINGS_FILE, rec_meta), (SAMPLES_FILE, samples_meta))
        if FINGERPRINT_KEY in meta
    }
    wrong = sorted(name for name, value in stored.items() if value != ds.fingerprint)
    if wrong:
        # the recordings table passed its digest: the samples changed, unless only the
        # recordings file's own record of the fingerprint differs from an intact samples file
        blamed = (
            RECORDINGS_FILE
            if wrong == [RECORDINGS_FILE] and SAMPLES_FILE in stored
            else SAMPLES_FILE
        )
        raise data_error(
            path / blamed,
            f"the dataset's content gives fingerprint {ds.fingerprint}, not the "
            f"{stored[wrong[0]]} stored in {wrong[0]} when it was written: {AFTER}",
        )


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
    SENSOR_TYPE: (_is_string, "a string"),
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
    # empty lists alone are written as a list of nulls by pyarrow's type inference
    "univariate_channels": (
        _nullable(
            lambda t: _is_list(t) and (_is_string(t.value_type) or pa.types.is_null(t.value_type))
        ),
        "a list of strings",
    ),
}


def _open_parquet(file: Path) -> pq.ParquetFile:
    """Open a Parquet file of the format, checking its version; columns are read later, one row
    group at a time, so that reading a large dataset never holds every column at once."""
    if not file.is_file():
        raise DataError(
            f"{file}: missing (a slipbench dataset folder holds {RECORDINGS_FILE} and {SAMPLES_FILE})"
        )
    try:  # pages written with a CRC are checked as they are read; older files have none
        pf = open_parquet(file, page_checksum_verification=True)
        schema = pf.schema_arrow
    except (pa.ArrowException, OSError) as exc:
        raise DataError(f"{file}: not a readable Parquet file ({one_line(exc)})") from None
    version = (schema.metadata or {}).get(VERSION_KEY)
    if version is None:
        raise data_error(
            file, f"no {VERSION_KEY.decode()} in the schema metadata; is this a slipbench dataset?"
        )
    if version.decode(errors="replace") != FORMAT_VERSION:
        raise data_error(
            file,
            f"format version {version.decode(errors='replace')!r} is not supported (this slipbench reads {FORMAT_VERSION!r})",
        )
    return pf


def _check_type(schema: pa.Schema, file: Path, name: str, check, type_name: str) -> None:
    if name not in schema.names:
        raise data_error(
            file,
            f"required column missing (columns present: {', '.join(schema.names)})",
            column=name,
        )
    if not check(schema.field(name).type):
        raise data_error(file, f"must be {type_name}, found {schema.field(name).type}", column=name)


# ----------------------------------------------------------------------------- recordings
def _read_recordings(file: Path) -> tuple[pd.DataFrame, dict[str, int], Mapping[bytes, bytes]]:
    """The canonical recordings, the lengths the file declares (its ``n_samples``), and its
    schema metadata."""
    pf = _open_parquet(file)
    table = pf.read()
    columns = {}
    for name, (check, type_name) in RECORDING_TYPES.items():
        if name in OPTIONAL and name not in table.column_names:
            continue
        _check_type(table.schema, file, name, check, type_name)
        columns[name] = table.column(name).to_pylist()  # plain Python values: every flavour alike
    declared = columns.pop("n_samples", [])
    rec = canonical_recordings(pd.DataFrame(columns), file)
    lengths = {rid: n for rid, n in zip(columns["recording_id"], declared) if n is not None}
    return rec, lengths, pf.schema_arrow.metadata or {}


# ----------------------------------------------------------------------------- samples
def _codes(chunk: pa.Array, index: pd.Index, file: Path, row0: int) -> np.ndarray:
    """Row -> position of its recording in the canonical recordings, for one chunk."""
    if chunk.null_count:
        raise data_error(
            file, f"null value at row {row0 + _first_null(chunk)}", column="recording_id"
        )
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
            raise data_error(
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
        raise data_error(
            file,
            f"slip must be true/false (or 1/0), or null for unlabelled; sample_index {int(index[i])} has {int(given[i])}",
            ids[codes[i]],
            "slip",
        )
    return pc.fill_null(ints, -1).to_numpy().astype(np.int8)


@dataclass
class _Placement:
    """Where the samples of ``file`` go: each recording's id (``ids``, ``index``), channel count,
    rows (``counts``), first row and first element in ``flat``, which receives the values."""

    file: Path
    ids: np.ndarray
    index: pd.Index
    n_ch: np.ndarray
    counts: np.ndarray
    flat: np.ndarray
    is_int: bool

    @cached_property
    def row_start(self) -> np.ndarray:
        return np.r_[0, np.cumsum(self.counts)]

    @cached_property
    def elem_start(self) -> np.ndarray:
        return np.r_[0, np.cumsum(self.counts * self.n_ch)]


def _read_samples(
    file: Path, rec: pd.DataFrame, declared: Mapping[str, int]
) -> tuple[dict, dict, Mapping[bytes, bytes]]:
    """Every recording's samples and labels, placed by ``sample_index`` whatever the row order,
    and the file's schema metadata; ``declared``: recording_id -> the n_samples that
    recordings.parquet gives."""
    pf = _open_parquet(file)
    schema = pf.schema_arrow
    has_slip = _check_sample_types(schema, file)
    value_type = schema.field("values").type.value_type
    dtype = np.float32 if value_type in (pa.float16(), pa.float32()) else np.float64
    ids = rec["recording_id"].to_numpy(dtype=object)
    index = pd.Index(ids)
    n_ch = rec["n_channels"].to_numpy()
    counts = _rows_per_recording(pf, file, ids, index, declared)
    place = _Placement(
        file, ids, index, n_ch, counts, np.empty(0, dtype), pa.types.is_integer(value_type)
    )
    row_start, elem_start = place.row_start, place.elem_start
    place.flat = np.empty(int(elem_start[-1]), dtype)

    # each row group's rows go where their recording and sample_index say
    n_rows = pf.metadata.num_rows
    filled = np.zeros(n_rows, bool)
    labels = np.full(n_rows, -1, np.int8) if has_slip else None
    for row0, table in _row_groups(
        pf, ["recording_id", "sample_index", "values"] + (["slip"] if has_slip else [])
    ):
        if table.num_rows == 0:
            continue
        table = table.combine_chunks()
        codes = _codes(table.column("recording_id").chunk(0), index, file, row0)
        si = _sample_indices(table.column("sample_index").chunk(0), place, codes, row0)
        dest = row_start[codes] + si
        again = filled[dest] | _repeated(dest)
        if again.any():
            i = int(np.argmax(again))
            raise data_error(
                file,
                f"sample_index {int(si[i])} appears more than once",
                ids[codes[i]],
                "sample_index",
            )
        filled[dest] = True
        _place_values(table.column("values").chunk(0), place, codes, si, row0)
        if labels is not None:  # the file has a slip column
            labels[dest] = _labels_of(table.column("slip").chunk(0), file, ids, codes, si)

    samples: dict[str, np.ndarray] = {}
    slip: dict[str, np.ndarray] = {}
    for k, rid in enumerate(ids):
        block = place.flat[elem_start[k] : elem_start[k + 1]]
        samples[rid] = block.reshape(int(counts[k]), int(n_ch[k]))
        if labels is not None:
            slip[rid] = labels[row_start[k] : row_start[k + 1]]
    return samples, slip, schema.metadata or {}


def _check_sample_types(schema: pa.Schema, file: Path) -> bool:
    """Refuse columns of the wrong type; whether the file has a ``slip`` column."""
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
    return has_slip


def _rows_per_recording(
    pf, file: Path, ids: np.ndarray, index: pd.Index, declared: Mapping[str, int]
) -> np.ndarray:
    """Rows of each recording, checked against what recordings.parquet declares."""
    if pf.metadata.num_rows == 0:
        raise data_error(file, "no samples")
    counts = np.zeros(len(ids), np.int64)
    for row0, table in _row_groups(pf, ["recording_id"]):
        for chunk in table.column(0).chunks:
            counts += np.bincount(_codes(chunk, index, file, row0), minlength=len(ids))
            row0 += len(chunk)
    if (counts == 0).any():
        raise data_error(
            file, "recording has no samples", ids[np.argmax(counts == 0)], "recording_id"
        )
    for k, rid in enumerate(ids):  # the writer's record of each length: rows lost at an end show
        if rid in declared and declared[rid] != counts[k]:
            raise data_error(
                file,
                f"{int(counts[k])} rows, but {RECORDINGS_FILE} gives n_samples {declared[rid]}: rows are missing "
                "or left over",
                rid,
                "sample_index",
            )
    if (counts < 2).any():
        raise data_error(
            file, "a recording needs at least 2 samples", ids[np.argmax(counts < 2)], "sample_index"
        )
    return counts


def _sample_indices(
    si_arr: pa.Array, place: _Placement, codes: np.ndarray, row0: int
) -> np.ndarray:
    """A chunk's sample indices, refused where null or outside their recording's rows."""
    file, ids, counts = place.file, place.ids, place.counts
    if si_arr.null_count:
        i = _first_null(si_arr)
        raise data_error(file, f"null value at row {row0 + i}", ids[codes[i]], "sample_index")
    si = si_arr.to_numpy().astype(np.int64)
    bad = (si < 0) | (si >= counts[codes])
    if bad.any():
        i = int(np.argmax(bad))
        raise data_error(
            file,
            f"sample_index {int(si[i])} (row {row0 + i}) is out of range: the recording has {int(counts[codes[i]])} "
            f"rows, so its indices must be 0 to {int(counts[codes[i]]) - 1}, each once",
            ids[codes[i]],
            "sample_index",
        )
    return si


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
    chunk: pa.Array, place: _Placement, codes: np.ndarray, si: np.ndarray, row0: int
) -> None:
    """Check one chunk of ``values`` (widths, nulls, finite, exact) and copy it into ``flat``."""
    file, ids, n_ch, flat, is_int = place.file, place.ids, place.n_ch, place.flat, place.is_int
    elem_start = place.elem_start
    if chunk.null_count:
        i = _first_null(chunk)
        raise data_error(
            file, f"null list of values at sample_index {int(si[i])}", ids[codes[i]], "values"
        )
    if pa.types.is_fixed_size_list(chunk.type):
        widths = np.full(len(chunk), chunk.type.list_size, np.int64)
    else:  # offsets, not pc.list_value_length: ten times faster on a million rows
        widths = np.diff(chunk.offsets.to_numpy()).astype(np.int64)
    bad = widths != n_ch[codes]
    if bad.any():
        i = int(np.argmax(bad))
        raise data_error(
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
        raise data_error(
            file, f"null channel value at sample_index {int(si[i])}", ids[codes[i]], "values"
        )
    raw = part.to_numpy()
    if is_int:
        too_big = np.abs(raw.astype(np.float64)) > EXACT_INT
        if too_big.any():
            i = row_of(int(np.argmax(too_big)))
            raise data_error(
                file,
                f"integer beyond 2**53 at sample_index {int(si[i])}: float64 cannot hold it exactly",
                ids[codes[i]],
                "values",
            )
    values = raw.astype(flat.dtype, copy=False)
    finite = np.isfinite(values)
    if not finite.all():
        i = row_of(int(np.argmin(finite)))
        raise data_error(
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
