"""Files that know they are damaged: page checksums and the stored content fingerprint.

Bytes flipped inside any column of either file of a small written dataset are refused by
`dataset validate` and `evaluate` (exit 2) naming that file; a file rewritten with other content
but the old metadata is refused by the fingerprint; datasets written before (no checksums, no
stored fingerprint) still read, with the same fingerprint."""

from __future__ import annotations

import errno
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest

from slipbench.data.integrity import page_checksums
from slipbench.data.read import read_dataset, read_description
from slipbench.data.schema import (
    FINGERPRINT_KEY,
    RECORDINGS_DIGEST_KEY,
    RECORDINGS_FILE,
    SAMPLES_FILE,
    SOURCE_KEY,
)
from slipbench.data.write import write_dataset
from slipbench.errors import DataError, EnvironmentFault


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


# ----------------------------------------------------------------------------- what validate says
def _from_another_tool(written: Path, to: Path, integers: bool = False) -> Path:
    """The dataset as another tool writes it: no page checksums, no stored fingerprint; the
    values as int64 where ``integers``; a source and citation in the metadata."""
    to.mkdir()
    for name in (RECORDINGS_FILE, SAMPLES_FILE):
        table = pq.read_table(written / name)
        if integers and name == SAMPLES_FILE:
            values = table.column("values").combine_chunks()
            ints = pa.LargeListArray.from_arrays(
                values.offsets, pc.cast(pc.round(pc.multiply(values.values, 100)), pa.int64())
            )
            table = table.set_column(table.schema.get_field_index("values"), "values", ints)
        meta = {b"slipbench.format_version": b"1"}
        if name == RECORDINGS_FILE:
            meta[SOURCE_KEY] = b"a lab's logger"
        pq.write_table(table.replace_schema_metadata(meta), to / name)
    return to


def test_checksums_are_read_from_the_page_headers(written, tmp_path):
    other = _from_another_tool(written, tmp_path / "other")
    for name in (RECORDINGS_FILE, SAMPLES_FILE):
        assert page_checksums(written / name) and not page_checksums(other / name)
        pq.write_table(pq.read_table(other / name), other / name, write_page_checksum=True)
        assert page_checksums(other / name)


def test_validate_says_where_bit_rot_cannot_be_detected_and_rewrite_adds_the_guards(
    written, tmp_path, cli
):
    other = _from_another_tool(written, tmp_path / "other", integers=True)
    code, out, err = cli(["dataset", "validate", str(other)])
    assert code == 0, err
    lines = out.splitlines()
    assert lines[0].startswith(f"{other}: valid slipbench dataset v1")
    assert lines[1:] == [
        f"warning: {other / name}: no page checksums and no stored fingerprint (written by "
        "another tool, or by an older slipbench): a flipped bit in it cannot be detected"
        for name in (RECORDINGS_FILE, SAMPLES_FILE)
    ] + [f"`slipbench dataset rewrite {other} NEW_FOLDER` writes a copy with both"]
    code, out, err = cli(["dataset", "rewrite", str(other), str(tmp_path / "new")])
    assert code == 0 and out == f"wrote {tmp_path / 'new'}\n", err
    code, out, err = cli(["dataset", "validate", str(tmp_path / "new")])
    assert code == 0 and out.splitlines()[1] == (
        f"{tmp_path / 'new'}: every page carries a checksum and the content its stored "
        "fingerprint: a damaged file is refused"
    )
    assert read_dataset(tmp_path / "new").fingerprint == read_dataset(other).fingerprint
    values = pq.read_schema(tmp_path / "new" / SAMPLES_FILE).field("values").type.value_type
    assert values == pa.int64()  # raw counts stay integers
    assert read_description(tmp_path / "new")["slipbench.source"] == "a lab's logger"


def test_a_full_disk_names_the_file_being_written(written, tmp_path, monkeypatch):
    """pyarrow's OSError names no file: write_dataset names the one it was writing, and leaves
    no hidden folder behind."""
    ds = read_dataset(written)
    real = pq.write_table

    def full(table, where, **kwargs):
        if str(where).endswith(SAMPLES_FILE):
            raise OSError(errno.ENOSPC, "Error writing bytes to file")
        return real(table, where, **kwargs)

    monkeypatch.setattr(pq, "write_table", full)
    with pytest.raises(EnvironmentFault) as err:
        write_dataset(tmp_path / "ds", ds.recordings, ds.samples, ds.slip_labels)
    assert str(err.value) == (
        f"cannot write {tmp_path / 'ds' / SAMPLES_FILE}: no space left on device (ENOSPC)"
    )
    assert list(tmp_path.iterdir()) == []


FSIZE = """
import resource, signal, sys
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # the kernel then fails the write with EFBIG
resource.setrlimit(resource.RLIMIT_FSIZE, (50_000, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))
from slipbench.app.cli import main
main(sys.argv[1:])
"""


@pytest.mark.slow
def test_dataset_synth_on_a_full_disk_names_the_file(tmp_path):
    """The issue's case, with a real kernel write failure (a file size limit, no root needed):
    `cannot write ?` became the file's path."""
    done = subprocess.run(
        [sys.executable, "-c", FSIZE, "dataset", "synth", str(tmp_path / "ds"), "--scale", "0.001"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert done.returncode == 5, done.stderr
    assert done.stderr == (
        f"error: cannot write {tmp_path / 'ds' / SAMPLES_FILE}: file too large for this file "
        "system or the process's file size limit (EFBIG)\n"
    )
    assert list(tmp_path.iterdir()) == []
