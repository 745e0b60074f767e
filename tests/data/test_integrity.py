"""Files that know they are damaged: page checksums and the stored content fingerprint.

Bytes flipped inside any column of either file of a small written dataset are refused by
`dataset validate` and `evaluate` (exit 2) naming that file; a file rewritten with other content
but the old metadata is refused by the fingerprint; datasets written before (no checksums, no
stored fingerprint) still read, with the same fingerprint."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest

from slipbench.data.read import read_dataset
from slipbench.data.schema import (
    FINGERPRINT_KEY,
    RECORDINGS_DIGEST_KEY,
    RECORDINGS_FILE,
    SAMPLES_FILE,
)
from slipbench.data.write import write_dataset
from slipbench.errors import DataError


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> Path:
    """Four recordings of two channels (slip and press, labelled per sample, two trials)."""
    rng = np.random.default_rng(0)
    rows, samples, labels = [], {}, {}
    for k in range(4):
        rid = f"r{k}"
        rows.append(
            dict(
                recording_id=rid,
                sensor_type="S",
                sensor_instance="u",
                scenario=("slip", "press")[k % 2],
                material=("wood", "foam")[k // 2],
                speed_mm_s=10.0 if k % 2 == 0 else None,
                sampling_rate_hz=100.0,
                channels=("a", "b"),
                units=("N", "N"),
                source="test",
                trial=f"t{k // 2}",
            )
        )
        samples[rid] = rng.normal(size=(400, 2))
        labels[rid] = (np.arange(400) >= 200).astype(np.int8) * (k % 2 == 0)
    return write_dataset(
        tmp_path_factory.mktemp("integrity") / "ds", pd.DataFrame(rows), samples, labels
    )


def _column_chunks(file: Path) -> list[tuple[str, int, int]]:
    """(column, first byte, length) of every column chunk of a Parquet file."""
    md = pq.ParquetFile(file).metadata
    out = []
    for g in range(md.num_row_groups):
        for c in range(md.num_columns):
            col = md.row_group(g).column(c)
            start = col.dictionary_page_offset or col.data_page_offset
            out.append((col.path_in_schema, start, col.total_compressed_size))
    return out


def _flipped(src: Path, dst: Path, name: str, at: int, n: int = 64) -> Path:
    shutil.copytree(src, dst)
    data = bytearray((dst / name).read_bytes())
    lo = max(0, min(at - n // 2, len(data) - n))
    data[lo : lo + n] = bytes(b ^ 0xFF for b in data[lo : lo + n])
    (dst / name).write_bytes(bytes(data))
    return dst


def test_fingerprint_and_checksums_are_stored(written):
    ds = read_dataset(written)
    for name in (RECORDINGS_FILE, SAMPLES_FILE):
        pf = pq.ParquetFile(written / name)
        assert pf.schema_arrow.metadata[FINGERPRINT_KEY].decode() == ds.fingerprint
        # every page of the file is checked: a pyarrow reader that verifies reads it whole
        assert pq.read_table(written / name, page_checksum_verification=True).num_rows > 0
    assert RECORDINGS_DIGEST_KEY in pq.read_schema(written / RECORDINGS_FILE).metadata


@pytest.mark.parametrize("name", [RECORDINGS_FILE, SAMPLES_FILE])
def test_flipped_bytes_in_any_column_are_refused_naming_the_file(written, tmp_path, cli, name):
    chunks = _column_chunks(written / name)
    assert {c for c, _, _ in chunks} >= (
        {"recording_id", "sample_index", "values.list.element", "slip"}
        if name == SAMPLES_FILE
        else {"recording_id", "material", "trial", "channels.list.element"}
    )
    size = (written / name).stat().st_size
    places = [(column, start + length // 2) for column, start, length in chunks]
    for k, (column, at) in enumerate(places + [("middle of the file", size // 2)]):
        bad = _flipped(written, tmp_path / f"bad{k}", name, at)
        code, out, err = cli(["dataset", "validate", str(bad)])
        assert code == 2, f"{column}: {out}"
        assert f"{bad / name}:" in err and len(err.strip().splitlines()) == 1, (column, err)


def test_evaluate_refuses_a_damaged_dataset(written, tmp_path, cli):
    """The issue's case: 64 bytes flipped inside samples.parquet changed a value and evaluated."""
    (column, start, length) = next(
        c for c in _column_chunks(written / SAMPLES_FILE) if c[0] == "values.list.element"
    )
    bad = _flipped(written, tmp_path / "bad", SAMPLES_FILE, start + length // 2)
    argv = ["evaluate", "--detector", "holweg", "--protocol", "window-size", "--quiet"]
    code, out, err = cli(
        argv + ["--dataset", str(bad), "--out", str(tmp_path / "res"), "--split", "grouped"]
    )
    assert code == 2 and f"{bad / SAMPLES_FILE}:" in err and "checksum" in err, err
    assert not (tmp_path / "res" / "results.parquet").exists()


def _rewrite(file: Path, change) -> None:
    """Rewrite a file with pyarrow, keeping its metadata: new checksums, old fingerprint."""
    table = pq.read_table(file)
    pq.write_table(change(table).replace_schema_metadata(table.schema.metadata), file)


def test_content_changed_after_writing_is_refused(written, tmp_path):
    edited = tmp_path / "material"
    shutil.copytree(written, edited)
    _rewrite(
        edited / RECORDINGS_FILE,
        lambda t: t.set_column(
            t.schema.get_field_index("material"),
            "material",
            pa.array(["cork"] * t.num_rows),
        ),
    )
    with pytest.raises(
        DataError, match=rf"{RECORDINGS_FILE}: its recordings give digest .*damaged"
    ):
        read_dataset(edited)

    edited = tmp_path / "values"
    shutil.copytree(written, edited)

    def scale(t: pa.Table) -> pa.Table:
        values = t.column("values").combine_chunks()
        bigger = pa.LargeListArray.from_arrays(values.offsets, pc.multiply(values.values, 1.5))
        return t.set_column(t.schema.get_field_index("values"), "values", bigger)

    _rewrite(edited / SAMPLES_FILE, scale)
    with pytest.raises(
        DataError, match=rf"{SAMPLES_FILE}: the dataset's content gives fingerprint .*not the"
    ):
        read_dataset(edited)
    # the samples rewritten by a writer that drops the metadata: recordings.parquet still
    # records the fingerprint, and its table is intact, so the samples are named
    table = pq.read_table(edited / SAMPLES_FILE)
    pq.write_table(
        table.replace_schema_metadata({b"slipbench.format_version": b"1"}), edited / SAMPLES_FILE
    )
    with pytest.raises(DataError, match=rf"{SAMPLES_FILE}: .*stored in {RECORDINGS_FILE}"):
        read_dataset(edited)

    # only recordings.parquet's record of the fingerprint differs: it is the one named
    edited = tmp_path / "footer"
    shutil.copytree(written, edited)
    table = pq.read_table(edited / RECORDINGS_FILE)
    meta = {**table.schema.metadata, FINGERPRINT_KEY: b"0123456789abcdef"}
    pq.write_table(table.replace_schema_metadata(meta), edited / RECORDINGS_FILE)
    with pytest.raises(DataError, match=rf"{RECORDINGS_FILE}: .*not the 0123456789abcdef"):
        read_dataset(edited)


def test_datasets_written_before_still_read(written, tmp_path):
    """No checksums and no stored fingerprint, as every dataset written before: read as always,
    to the same content and fingerprint."""
    old = tmp_path / "old"
    old.mkdir()
    for name in (RECORDINGS_FILE, SAMPLES_FILE):
        table = pq.read_table(written / name)
        meta = {
            k: v
            for k, v in table.schema.metadata.items()
            if k not in (FINGERPRINT_KEY, RECORDINGS_DIGEST_KEY)
        }
        pq.write_table(table.replace_schema_metadata(meta), old / name)
        assert FINGERPRINT_KEY not in pq.read_schema(old / name).metadata
    assert read_dataset(old).fingerprint == read_dataset(written).fingerprint
