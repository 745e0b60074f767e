"""Samples whose magnitude would overflow a detector's arithmetic (a 1e308, or every sample
1e300) are the data's fault: refused by `dataset validate`, `evaluate` and a dataset built in
memory, naming the recording, where the sample is and its value; never blamed on a detector."""

from __future__ import annotations

import shutil

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from slipbench.data.format import Dataset
from slipbench.data.read import read_dataset
from slipbench.data.schema import MAX_MAGNITUDE, SAMPLES_FILE, VERSION_KEY
from slipbench.errors import DataError


def _rewritten(unit, folder, change) -> None:
    """``unit`` copied to ``folder`` with its values as float64 changed by ``change`` (flat
    array, in place), written as another tool would: no fingerprint, no checksums."""
    shutil.copytree(unit, folder)
    table = pq.read_table(folder / SAMPLES_FILE)
    values = table.column("values").combine_chunks()
    flat = values.flatten().to_numpy().astype(np.float64)
    change(flat)
    lists = pa.ListArray.from_arrays(values.offsets, pa.array(flat))
    table = table.set_column(table.column_names.index("values"), "values", lists)
    pq.write_table(table.replace_schema_metadata({VERSION_KEY: b"1"}), folder / SAMPLES_FILE)
    (folder / "recordings.parquet").write_bytes(
        _without_fingerprint((folder / "recordings.parquet").read_bytes())
    )


def _without_fingerprint(data: bytes) -> bytes:
    table = pq.read_table(pa.BufferReader(data))
    sink = pa.BufferOutputStream()
    pq.write_table(table.replace_schema_metadata({VERSION_KEY: b"1"}), sink)
    return sink.getvalue().to_pybytes()


def _one_huge(flat: np.ndarray) -> None:
    flat[7] = 1e308


def _all_huge(flat: np.ndarray) -> None:
    flat[:] = 1e300


@pytest.mark.parametrize("change, value", [(_one_huge, "1e+308"), (_all_huge, "1e+300")])
def test_samples_that_overflow_are_refused_naming_recording_and_value(
    unit, tmp_path, cli, change, value
):
    data = tmp_path / "data"
    _rewritten(unit, data, change)
    first = read_dataset(unit).recordings["recording_id"].iloc[0]
    said = f"recording {first!r}: column 'values': value {value} at sample "
    code, _, err = cli(["dataset", "validate", str(data)])
    assert code == 2 and said in err and "beyond 9e+15 in magnitude" in err, err
    assert len(err.strip().splitlines()) == 1
    evaluate = ["evaluate", "--detector", "holweg", "--protocol", "window-size"]
    code, _, err = cli([*evaluate, "--dataset", str(data), "--out", str(tmp_path / "out")])
    assert code == 2 and said in err and "detector" not in err.split("magnitude")[0], err
    assert not (tmp_path / "out").exists()


def test_a_dataset_in_memory_is_held_to_the_same_bound(unit):
    ds = read_dataset(unit)
    rid = ds.recordings["recording_id"].iloc[2]
    samples = {k: v.astype(np.float64) for k, v in ds.samples.items()}
    samples[rid][3, 0] = -2 * MAX_MAGNITUDE
    with pytest.raises(DataError, match=f"{rid}.*value -1.80144e\\+16 at sample 3, channel"):
        Dataset(ds.recordings, samples, ds.slip_labels)
    samples[rid][3, 0] = -MAX_MAGNITUDE  # the bound itself passes
    assert Dataset(ds.recordings, samples, ds.slip_labels).samples[rid][3, 0] == -MAX_MAGNITUDE
    samples[rid][3, 0] = np.nan
    with pytest.raises(DataError, match="non-finite value nan .* at sample 3"):
        Dataset(ds.recordings, samples, ds.slip_labels)
