"""The optional ``univariate_channels`` column: which channels the paper's s uses. Absent, null,
empty or naming every channel, a dataset reads, hashes and reduces as one without it; naming
some, s comes from those alone, the fingerprint says so, and it survives writing and reading;
names that are not the recording's channels are refused naming recording and column."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from slipbench.data.format import Dataset
from slipbench.data.read import read_dataset
from slipbench.data.schema import RECORDINGS_FILE, VERSION_KEY
from slipbench.data.signals import Signals, univariate
from slipbench.data.write import write_dataset
from slipbench.errors import DataError

COLUMN = "univariate_channels"
RNG = np.random.default_rng(0)
# "a" has a pressure channel beside two electrodes resting at thousands of counts: their norm
# would swamp the pressure's changes
SAMPLES = {
    "a": np.column_stack([RNG.normal(0, 1, 50), 3000 + RNG.normal(0, 2, (50, 2))]),
    "b": RNG.normal(0, 1, (40, 3)),
}


def _recordings(**columns) -> pd.DataFrame:
    rec = pd.DataFrame(
        {
            "recording_id": ["a", "b"],
            "sensor_type": ["S", "S"],
            "sensor_instance": ["index", "index"],
            "scenario": ["slip", "press"],
            "material": ["PVC", "PVC"],
            "speed_mm_s": [5.0, None],
            "sampling_rate_hz": [100.0, 100.0],
            "channels": [("pac", "e1", "e2"), ("pac", "e1", "e2")],
            "units": [("count",) * 3] * 2,
            "source": ["test", "test"],
        }
    )
    for name, values in columns.items():
        rec[name] = values
    return rec


def _dataset(**columns) -> Dataset:
    return Dataset(_recordings(**columns), SAMPLES)


@pytest.mark.parametrize(
    "values",
    [
        [None, None],
        [(), []],
        [None, ("pac", "e1", "e2")],  # every channel: the same s as none named
        [("e2", "pac", "e1"), float("nan")],
    ],
)
def test_none_named_reads_hashes_and_reduces_as_a_dataset_without_the_column(values):
    plain, given = _dataset(), _dataset(**{COLUMN: values})
    assert list(given.recordings[COLUMN]) == [(), ()] == list(plain.recordings[COLUMN])
    assert given.fingerprint == plain.fingerprint
    s = Signals.from_dataset(given)
    np.testing.assert_array_equal(s.buffer, Signals.from_dataset(plain).buffer)
    np.testing.assert_array_equal(s.buffer[:49], univariate(SAMPLES["a"]))


def test_named_channels_make_s_and_change_the_fingerprint():
    plain = _dataset()
    pac = _dataset(**{COLUMN: [["pac"], None]})
    assert list(pac.recordings[COLUMN]) == [("pac",), ()]
    assert pac.fingerprint != plain.fingerprint
    s = Signals.from_dataset(pac)
    np.testing.assert_array_equal(s.buffer[:49], univariate(SAMPLES["a"][:, :1]))
    np.testing.assert_array_equal(s.buffer[49:], univariate(SAMPLES["b"]))  # "b": all three
    # the pressure's changes, not the electrodes' offsets: |s| is that of the pac channel
    assert np.abs(s.buffer[:49]).mean() > 0.5
    # names are kept in the order of the channels: the same s, the same content
    both = _dataset(**{COLUMN: [["e2", "pac"], None]})
    again = _dataset(**{COLUMN: [["pac", "e2"], None]})
    assert both.recordings[COLUMN][0] == ("pac", "e2") and both.fingerprint == again.fingerprint


def test_written_only_where_named_and_read_back(tmp_path):
    plain = write_dataset(tmp_path / "plain", _recordings(**{COLUMN: [None, []]}), SAMPLES)
    assert COLUMN not in pq.read_schema(plain / RECORDINGS_FILE).names
    assert read_dataset(plain).fingerprint == _dataset().fingerprint

    named = write_dataset(tmp_path / "named", _recordings(**{COLUMN: [("pac",), None]}), SAMPLES)
    table = pq.read_table(named / RECORDINGS_FILE)
    assert table.column(COLUMN).to_pylist() == [["pac"], []]
    ds = read_dataset(named)  # its stored fingerprint and digest hold
    assert list(ds.recordings[COLUMN]) == [("pac",), ()]
    assert ds.fingerprint == _dataset(**{COLUMN: [["pac"], None]}).fingerprint


def _lab_file(tmp_path, column: pa.Array):
    """A lab's own recordings file (format version only) with the given column."""
    path = write_dataset(tmp_path / "ds", _recordings(), SAMPLES)
    table = pq.read_table(path / RECORDINGS_FILE).append_column(COLUMN, column)
    pq.write_table(table.replace_schema_metadata({VERSION_KEY: b"1"}), path / RECORDINGS_FILE)
    for f in path.iterdir():  # drop the stored fingerprints: the content is the lab's own
        t = pq.read_table(f)
        pq.write_table(t.replace_schema_metadata({VERSION_KEY: b"1"}), f)
    return path


def test_a_lab_may_write_it_in_any_list_flavour(tmp_path):
    large = pa.array([["pac"], None], pa.large_list(pa.large_string()))
    ds = read_dataset(_lab_file(tmp_path, large))
    assert list(ds.recordings[COLUMN]) == [("pac",), ()]
    empty = pa.array([[], []])  # pyarrow infers list<null> for empty lists alone
    assert empty.type == pa.list_(pa.null())
    assert list(read_dataset(_lab_file(tmp_path / "e", empty)).recordings[COLUMN]) == [(), ()]


@pytest.mark.parametrize(
    "values, message",
    [
        (
            [["pac", "e9"], None],
            r"recording 'a': column 'univariate_channels': names 'e9', not among",
        ),
        ([None, ["pac", "pac"]], r"recording 'b': column 'univariate_channels': names 'pac' more"),
        ([None, "pac"], r"recording 'b': column 'univariate_channels': must be a list of strings"),
        ([[1], None], r"recording 'a': column 'univariate_channels': must be a list of strings"),
    ],
)
def test_names_that_are_not_channels_are_refused(values, message):
    with pytest.raises(DataError, match=message):
        _dataset(**{COLUMN: values})


def test_a_file_naming_an_unknown_channel_is_refused_naming_it(tmp_path):
    path = _lab_file(tmp_path, pa.array([["pressure"], None]))
    with pytest.raises(DataError, match=r"recording 'a': column 'univariate_channels'") as err:
        read_dataset(path)
    assert RECORDINGS_FILE in str(err.value)
    wrong = _lab_file(tmp_path / "w", pa.array([1, 2]))
    with pytest.raises(DataError, match=r"column 'univariate_channels': must be a list of strings"):
        read_dataset(wrong)
