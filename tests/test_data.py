"""The dataset format: round trip, and refusal of every kind of broken file with a message
naming the file, recording and column."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from slipbench.data import RECORDINGS_FILE, SAMPLES_FILE, VERSION_KEY, info, read_dataset, write_dataset
from slipbench.errors import DataError


def _tiny(tmp_path, **changes):
    rec = pd.DataFrame({
        "recording_id": ["a", "b"], "sensor_type": ["S", "S"], "sensor_instance": ["index", "index"],
        "scenario": ["slip", "press"], "material": ["PVC", "PVC"], "speed_mm_s": [5.0, None],
        "sampling_rate_hz": [1000.0, 1000.0], "channels": [("x", "y"), ("x", "y")],
        "units": [("N", "N"), ("N", "N")], "source": ["test", "test"],
    })
    samples = {"a": np.arange(20, dtype=np.float32).reshape(10, 2), "b": np.ones((6, 2), np.float32)}
    return write_dataset(tmp_path / "ds", rec, samples, {"a": np.ones(10, bool), "b": np.zeros(6, bool)})


def _rewrite(path, name, mutate):
    """Apply ``mutate`` to one file's table, keeping the format version metadata."""
    table = pq.read_table(path / name)
    meta = table.schema.metadata
    table = mutate(table)
    pq.write_table(table.replace_schema_metadata(meta), path / name)


def test_round_trip(tmp_path):
    ds = read_dataset(_tiny(tmp_path))
    assert list(ds.recordings["recording_id"]) == ["a", "b"]
    np.testing.assert_array_equal(ds.samples["a"], np.arange(20, dtype=np.float32).reshape(10, 2))
    assert ds.slip_labels["a"].all() and not ds.slip_labels["b"].any()
    assert ds.recordings["channels"][0] == ("x", "y")
    assert len(ds.fingerprint) == 16
    assert pq.read_schema(tmp_path / "ds" / SAMPLES_FILE).metadata[VERSION_KEY] == b"1"


def test_writer_refuses_to_overwrite(tmp_path):
    path = _tiny(tmp_path)
    with pytest.raises(DataError, match="already exists"):
        _tiny(tmp_path)
    assert read_dataset(path)  # untouched


def test_synthetic_dataset_validates(small):
    table = info(small)
    assert set(table["scenario"]) == {"slip", "press", "free-space"}
    assert set(small.recordings["sensor_type"]) == {"Nano17", "OptoForce20", "BioTacSP"}
    assert len(small.sensors()) == 8


@pytest.mark.parametrize(
    "name, mutate, message",
    [
        (SAMPLES_FILE, lambda t: t.drop_columns(["sample_index"]), r"column 'sample_index': required column missing"),
        (RECORDINGS_FILE, lambda t: t.drop_columns(["sampling_rate_hz"]), r"column 'sampling_rate_hz': required column missing"),
        (RECORDINGS_FILE, lambda t: t.set_column(0, "recording_id", pa.array(["a", "a"])), r"recording 'a': column 'recording_id': recording_id is not unique"),
        (RECORDINGS_FILE, lambda t: t.set_column(6, "sampling_rate_hz", pa.array([1000.0, -1.0])), r"recording 'b': column 'sampling_rate_hz': sampling rate must be a finite positive"),
        (RECORDINGS_FILE, lambda t: t.set_column(3, "scenario", pa.array(["slip", "poke"])), r"recording 'b': column 'scenario': scenario 'poke'"),
        (RECORDINGS_FILE, lambda t: t.set_column(8, "units", pa.array([["N"], ["N", "N"]])), r"recording 'a': column 'units'"),
        (SAMPLES_FILE, lambda t: t.set_column(2, "values", pa.array([[0.0, float("nan")]] + [[1.0, 1.0]] * 15, pa.list_(pa.float32()))), r"recording 'a': column 'values': non-finite value .* sample_index 0"),
        (SAMPLES_FILE, lambda t: t.set_column(1, "sample_index", pa.array(list(range(9)) + [10] + list(range(6)), pa.int64())), r"recording 'a': column 'sample_index': sample_index must run"),
        (SAMPLES_FILE, lambda t: t.set_column(2, "values", pa.array([[1.0]] + [[1.0, 1.0]] * 15, pa.list_(pa.float32()))), r"recording 'a': column 'values': row 0 has 1 values but the recording has 2 channels"),
        (SAMPLES_FILE, lambda t: t.take(list(range(10, 16)) + list(range(10)))[:6], r"recording 'a': column 'recording_id': recording has no samples"),
        (SAMPLES_FILE, lambda t: t.take([0, 1, 10, 2, 3, 4, 5, 6, 7, 8, 9, 11, 12, 13, 14, 15]), r"column 'recording_id': samples of this recording are not in one contiguous block"),
        (SAMPLES_FILE, lambda t: t.set_column(2, "values", t.column("values").cast(pa.list_(pa.string()))), r"column 'values': must be a list of floats"),
    ],
)
def test_broken_files_are_refused(tmp_path, name, mutate, message):
    path = _tiny(tmp_path)
    _rewrite(path, name, mutate)
    with pytest.raises(DataError, match=message) as err:
        read_dataset(path)
    assert name in str(err.value)


def test_missing_version_and_missing_file(tmp_path):
    path = _tiny(tmp_path)
    table = pq.read_table(path / RECORDINGS_FILE)
    pq.write_table(table.replace_schema_metadata({}), path / RECORDINGS_FILE)
    with pytest.raises(DataError, match="format_version"):
        read_dataset(path)
    (path / SAMPLES_FILE).unlink()
    with pytest.raises(DataError):
        read_dataset(path)
    with pytest.raises(DataError, match="not a dataset folder"):
        read_dataset(tmp_path / "nowhere")
