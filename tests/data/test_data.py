"""The dataset format: round trip, what labs write (every Arrow flavour, pandas 3 defaults,
integer counts, unlabelled samples, trials, per-recording rates), canonical order, content
fingerprint, and refusal of broken files with a message naming file, recording and column."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from slipbench.app.info import info
from slipbench.data.format import Dataset
from slipbench.data.read import read_dataset
from slipbench.data.schema import (
    RATE_TOLERANCE,
    RECORDINGS_FILE,
    SAMPLES_FILE,
    SCENARIOS,
    VERSION_KEY,
)
from slipbench.data.signals import univariate
from slipbench.data.write import write_dataset
from slipbench.errors import DataError

META = {VERSION_KEY: b"1"}


def _frame(**changes) -> pd.DataFrame:
    rec = pd.DataFrame(
        {
            "recording_id": ["a", "b"],
            "sensor_type": ["S", "S"],
            "sensor_instance": ["index", "index"],
            "scenario": ["slip", "press"],
            "material": ["PVC", "PVC"],
            "speed_mm_s": [5.0, None],
            "sampling_rate_hz": [1000.0, 1000.0],
            "channels": [("x", "y"), ("x", "y")],
            "units": [("N", "N"), ("N", "N")],
            "source": ["test", "test"],
        }
    )
    for name, values in changes.items():
        rec[name] = values
    return rec


SAMPLES = {"a": np.arange(20, dtype=np.float32).reshape(10, 2), "b": np.ones((6, 2), np.float32)}


def _tiny(tmp_path, name="ds"):
    return write_dataset(
        tmp_path / name, _frame(), SAMPLES, {"a": np.ones(10, bool), "b": np.zeros(6, bool)}
    )


def _rewrite(path, name, mutate):
    """Apply ``mutate`` to one file's table, keeping the format version metadata (not the
    stored fingerprint: the content is a lab's own, as if written without slipbench)."""
    table = pq.read_table(path / name)
    meta = {k: v for k, v in table.schema.metadata.items() if k == b"slipbench.format_version"}
    table = mutate(table)
    pq.write_table(table.replace_schema_metadata(meta), path / name)


def _same(x: Dataset, y: Dataset) -> None:
    columns = [c for c in x.recordings.columns]
    pd.testing.assert_frame_equal(
        x.recordings[columns].astype(object), y.recordings[columns].astype(object)
    )
    assert list(x.samples) == list(y.samples)
    for rid in x.samples:
        assert x.samples[rid].dtype == y.samples[rid].dtype
        np.testing.assert_array_equal(x.samples[rid], y.samples[rid])
    assert list(x.slip_labels) == list(y.slip_labels)
    for rid in x.slip_labels:
        np.testing.assert_array_equal(x.slip_labels[rid], y.slip_labels[rid])
    assert x.fingerprint == y.fingerprint


def test_round_trip(tmp_path):
    ds = read_dataset(_tiny(tmp_path))
    assert list(ds.recordings["recording_id"]) == ["a", "b"]
    np.testing.assert_array_equal(ds.samples["a"], SAMPLES["a"])
    assert ds.samples["a"].dtype == np.float32  # float32 stays float32
    assert ds.slip_labels["a"].dtype == np.int8 and ds.slip_labels["a"].tolist() == [1] * 10
    assert ds.slip_labels["b"].tolist() == [0] * 6
    assert ds.recordings["channels"][0] == ("x", "y")
    assert list(ds.recordings["trial"]) == [
        "a",
        "b",
    ]  # no trial column: each recording is its own trial
    assert list(ds.recordings["unit_rate_hz"]) == [1000.0, 1000.0]
    assert list(ds.recordings["n_samples"]) == [10, 6]
    assert pq.read_table(tmp_path / "ds" / RECORDINGS_FILE).column("n_samples").to_pylist() == [
        10,
        6,
    ]
    assert len(ds.fingerprint) == 16
    assert pq.read_schema(tmp_path / "ds" / SAMPLES_FILE).metadata[VERSION_KEY] == b"1"
    assert (
        "trial" not in pq.read_schema(tmp_path / "ds" / RECORDINGS_FILE).names
    )  # the frame had none
    assert SCENARIOS == ("slip", "press", "free-space", "hold-slip")


def test_written_folder_follows_the_umask(tmp_path):
    import os

    old = os.umask(0o002)
    try:
        path = _tiny(tmp_path)
    finally:
        os.umask(old)
    assert path.stat().st_mode & 0o777 == 0o775
    assert (path / SAMPLES_FILE).stat().st_mode & 0o777 == 0o664


def test_writer_refuses_to_overwrite(tmp_path):
    path = _tiny(tmp_path)
    with pytest.raises(DataError, match="already exists"):
        _tiny(tmp_path)
    assert read_dataset(path)  # untouched


def test_writer_checks_before_writing(tmp_path):
    bad = {"a": SAMPLES["a"].copy(), "b": SAMPLES["b"]}
    bad["a"][3, 1] = np.nan
    with pytest.raises(DataError, match=r"recording 'a': column 'values': non-finite"):
        write_dataset(tmp_path / "x", _frame(), bad)
    with pytest.raises(
        DataError,
        match=r"recording 'a': column 'slip': a hold-slip recording needs per-sample labels",
    ):
        write_dataset(tmp_path / "x", _frame(scenario=["hold-slip", "press"]), SAMPLES)
    with pytest.raises(
        DataError,
        match=r"recording 'a': column 'slip': labels must be bool, or int with -1 unlabelled",
    ):
        write_dataset(tmp_path / "x", _frame(), SAMPLES, {"a": np.full(10, 2)})
    with pytest.raises(DataError, match=r"recording 'b': column 'slip': 5 labels for 6 samples"):
        write_dataset(tmp_path / "x", _frame(), SAMPLES, {"b": np.zeros(5, bool)})
    with pytest.raises(
        DataError,
        match=r"recording 'b': column 'values': samples must have shape \(n >= 2, 2 channels\)",
    ):
        write_dataset(tmp_path / "x", _frame(), {"a": SAMPLES["a"], "b": np.ones((6, 3))})
    assert list(tmp_path.iterdir()) == []  # nothing half-written, no temporary folder left


def test_synthetic_dataset_validates(small):
    table = info(small)
    assert set(table["scenario"]) == {"slip", "press", "free-space", "hold-slip"}
    assert set(small.recordings["sensor_type"]) == {"Nano17", "OptoForce20", "BioTacSP"}
    assert len(small.sensors()) == 8
    assert small.recordings["recording_id"].is_monotonic_increasing


# ----------------------------------------------------------------------------- what labs write
def test_pandas_3_defaults_are_read(tmp_path):
    """pandas 3 turns str columns into large_string; lists of ints into list<int64>; a column of
    True/False/None into bool with nulls. Integer counts read as float64, exactly."""
    rec = _frame(trial=["t1", None])
    rec["channels"] = rec["channels"].map(list)
    rec["units"] = rec["units"].map(list)
    counts = {"a": np.arange(20).reshape(10, 2) * 1_000_003, "b": np.full((6, 2), 2**40)}
    rows = [
        (r, i, counts[r][i].tolist(), None if i == 0 else bool(r == "a"))
        for r in ("b", "a")
        for i in range(len(counts[r]))
    ]
    samples = pd.DataFrame(rows, columns=["recording_id", "sample_index", "values", "slip"])
    path = tmp_path / "p3"
    path.mkdir()
    for frame, name in ((rec, RECORDINGS_FILE), (samples, SAMPLES_FILE)):
        table = pa.Table.from_pandas(frame, preserve_index=False)
        pq.write_table(
            table.replace_schema_metadata({**table.schema.metadata, **META}), path / name
        )
    schema = pq.read_schema(path / RECORDINGS_FILE)
    assert schema.field("sensor_type").type == pa.large_string()  # what pandas 3 writes
    assert pq.read_schema(path / SAMPLES_FILE).field("values").type.value_type == pa.int64()
    ds = read_dataset(path)
    assert ds.samples["a"].dtype == np.float64
    np.testing.assert_array_equal(ds.samples["b"], np.full((6, 2), 2.0**40))
    np.testing.assert_array_equal(ds.samples["a"], counts["a"].astype(np.float64))
    assert ds.slip_labels["a"].tolist() == [-1] + [1] * 9  # null: unlabelled
    assert list(ds.recordings["trial"]) == ["t1", "b"]
    assert ds.recordings["material"].tolist() == ["PVC", "PVC"]


STRINGS = [
    pa.string(),
    pa.large_string(),
    pa.string_view(),
    pa.dictionary(pa.int8(), pa.string()),
    pa.dictionary(pa.int32(), pa.large_string()),
]
LISTS = [pa.list_, pa.large_list, lambda t: pa.list_(t, 2)]


@pytest.mark.parametrize("string", STRINGS, ids=str)
@pytest.mark.parametrize("make_list", LISTS, ids=["list", "large_list", "fixed_size_list"])
def test_every_string_and_list_flavour(tmp_path, string, make_list):
    reference = read_dataset(_tiny(tmp_path, "ref"))
    path = _tiny(tmp_path)

    def recordings(t: pa.Table) -> pa.Table:
        for name in (
            "recording_id",
            "sensor_type",
            "sensor_instance",
            "scenario",
            "material",
            "source",
        ):
            t = t.set_column(t.schema.get_field_index(name), name, t.column(name).cast(string))
        for name in ("channels", "units"):
            t = t.set_column(
                t.schema.get_field_index(name), name, t.column(name).cast(make_list(pa.string()))
            )
        return t

    def samples(t: pa.Table) -> pa.Table:
        rid = t.column("recording_id").cast(pa.string()).cast(string)
        t = t.set_column(0, "recording_id", rid)
        return t.set_column(2, "values", t.column("values").cast(make_list(pa.float32())))

    _rewrite(path, RECORDINGS_FILE, recordings)
    _rewrite(path, SAMPLES_FILE, samples)
    _same(read_dataset(path), reference)


@pytest.mark.parametrize(
    "value_type, dtype",
    [
        (pa.int16(), np.float64),
        (pa.uint32(), np.float64),
        (pa.int64(), np.float64),
        (pa.float16(), np.float32),
        (pa.float32(), np.float32),
        (pa.float64(), np.float64),
    ],
)
def test_value_types(tmp_path, value_type, dtype):
    path = _tiny(tmp_path)
    _rewrite(
        path,
        SAMPLES_FILE,
        lambda t: t.set_column(2, "values", t.column("values").cast(pa.large_list(value_type))),
    )
    ds = read_dataset(path)
    assert ds.samples["a"].dtype == dtype
    np.testing.assert_array_equal(ds.samples["a"], SAMPLES["a"])
    assert (
        ds.fingerprint == read_dataset(_tiny(tmp_path, "ref")).fingerprint
    )  # the same numbers: the same data


def test_writer_keeps_integer_counts_exact(tmp_path):
    counts = {
        "a": np.arange(20, dtype=np.int64).reshape(10, 2) + 2**30 + 1,
        "b": np.ones((6, 2), np.int32),
    }
    path = write_dataset(tmp_path / "ds", _frame(), counts)
    assert pq.read_schema(path / SAMPLES_FILE).field("values").type.value_type == pa.int64()
    np.testing.assert_array_equal(read_dataset(path).samples["a"], counts["a"])


def test_slip_labels_null_means_unlabelled(tmp_path):
    labels = {
        "a": np.array([-1, -1, 0, 0, 1, 1, 1, 1, -1, -1], np.int8)
    }  # b: left out, so unlabelled
    path = write_dataset(tmp_path / "ds", _frame(), SAMPLES, labels)
    assert pq.read_table(path / SAMPLES_FILE).column("slip").null_count == 4 + 6
    ds = read_dataset(path)
    np.testing.assert_array_equal(ds.slip_labels["a"], labels["a"])
    assert ds.slip_labels["b"].tolist() == [-1] * 6


def test_integer_slip_column(tmp_path):
    path = _tiny(tmp_path)
    _rewrite(
        path,
        SAMPLES_FILE,
        lambda t: t.set_column(3, "slip", pa.array([1] * 10 + [None] + [0] * 5, pa.int8())),
    )
    _rewrite(path, RECORDINGS_FILE, lambda t: t)  # a lab's own files: no stored fingerprint
    assert read_dataset(path).slip_labels["b"].tolist() == [-1, 0, 0, 0, 0, 0]


def test_hold_slip_recordings(tmp_path):
    hold_slip = np.array(
        [0, 0, 0, 0, 1, 1, 1, -1, -1, -1], np.int8
    )  # holds, slips at 4, then drops
    path = write_dataset(
        tmp_path / "ok", _frame(scenario=["hold-slip", "press"]), SAMPLES, {"a": hold_slip}
    )
    assert read_dataset(path).slip_labels["a"].tolist() == hold_slip.tolist()
    held = write_dataset(
        tmp_path / "held",
        _frame(scenario=["hold-slip", "press"]),
        SAMPLES,
        {"a": np.zeros(10, np.int8)},
    )
    assert (
        read_dataset(held).slip_labels["a"].tolist() == [0] * 10
    )  # a trial that held throughout: no onset
    for name, labels, message in [
        ("none", {"a": np.full(10, -1, np.int8)}, "no sample labelled no-slip before its onset"),
        (
            "nohold",
            {"a": np.array([-1, -1] + [1] * 8, np.int8)},
            "no sample labelled no-slip before its onset",
        ),
    ]:
        with pytest.raises(DataError, match=message):
            write_dataset(tmp_path / name, _frame(scenario=["hold-slip", "press"]), SAMPLES, labels)
    # the reader refuses a file that lacks the labels: file, recording and column named
    path = _tiny(tmp_path, "nolabels")
    _rewrite(
        path,
        RECORDINGS_FILE,
        lambda t: t.set_column(3, "scenario", pa.array(["hold-slip", "press"])),
    )
    _rewrite(path, SAMPLES_FILE, lambda t: t.drop_columns(["slip"]))
    with pytest.raises(
        DataError,
        match=rf"{SAMPLES_FILE}: recording 'a': column 'slip': a hold-slip recording needs per-sample labels",
    ):
        read_dataset(path)


def test_trial_column(tmp_path):
    path = write_dataset(tmp_path / "ds", _frame(trial=["hand-1", None]), SAMPLES)
    assert pq.read_schema(path / RECORDINGS_FILE).field("trial").type == pa.string()
    ds = read_dataset(path)
    assert list(ds.recordings["trial"]) == ["hand-1", "b"]
    assert ds.fingerprint == Dataset(_frame(trial=["hand-1", "b"]), SAMPLES).fingerprint
    assert ds.fingerprint != Dataset(_frame(trial=["hand-1", "hand-1"]), SAMPLES).fingerprint


def test_rates_of_a_unit_pool_at_their_median(tmp_path):
    ids = [f"r{i}" for i in range(5)]
    rates = [59.738499926, 60.0, 59.9, 59.85, 59.7]
    rec = pd.DataFrame(
        {
            "recording_id": ids,
            "sensor_type": "Taxel",
            "sensor_instance": "left",
            "scenario": "slip",
            "material": None,
            "speed_mm_s": None,
            "sampling_rate_hz": rates,
            "channels": [("c",)] * 5,
            "units": [("count",)] * 5,
            "source": None,
        }
    )
    samples = {r: np.arange(4, dtype=np.float64)[:, None] for r in ids}
    ds = read_dataset(write_dataset(tmp_path / "ok", rec, samples))
    assert list(ds.recordings["sampling_rate_hz"]) == rates
    assert set(ds.recordings["unit_rate_hz"]) == {np.median(rates)}
    beyond = rec.assign(
        sampling_rate_hz=[59.7, 60.0, 59.9, 59.7 * (1 + RATE_TOLERANCE) + 0.01, 59.8]
    )
    with pytest.raises(DataError) as err:
        write_dataset(tmp_path / "bad", beyond, samples)
    message = str(err.value)
    assert "sensor 'Taxel' unit 'left'" in message and "column 'sampling_rate_hz'" in message
    assert (
        "lowest 59.7 Hz in recording(s) 'r0'" in message
        and "highest 60.307 Hz in recording(s) 'r3'" in message
    )
    assert "np." not in message
    # another unit may have its own rate
    other = beyond.assign(
        sensor_instance=["left", "left", "left", "right", "right"],
        sampling_rate_hz=[59.7, 60.0, 59.9, 100.0, 100.0],
    )
    assert (
        list(
            read_dataset(write_dataset(tmp_path / "two", other, samples)).recordings["unit_rate_hz"]
        )
        == [59.9] * 3 + [100.0] * 2
    )


# ----------------------------------------------------------------------------- canonical order and fingerprint
def test_row_order_of_either_file_does_not_matter(tmp_path):
    reference = read_dataset(_tiny(tmp_path, "ref"))
    path = _tiny(tmp_path)
    rng = np.random.default_rng(0)
    _rewrite(path, RECORDINGS_FILE, lambda t: t.take([1, 0]))
    _rewrite(path, SAMPLES_FILE, lambda t: t.take(rng.permutation(t.num_rows)))
    _same(read_dataset(path), reference)


def test_fingerprint_is_of_content_not_of_bytes(tmp_path):
    ds = read_dataset(_tiny(tmp_path))
    assert (
        ds.fingerprint
        == Dataset(_frame(), SAMPLES, {"a": np.ones(10, bool), "b": np.zeros(6, bool)}).fingerprint
    )
    assert (
        ds.fingerprint
        == Dataset(
            _frame().iloc[::-1],
            {k: v.astype(np.float64) for k, v in SAMPLES.items()},
            {"a": np.ones(10, np.int8), "b": np.zeros(6, np.int8)},
        ).fingerprint
    )
    # the same tables written with other writer settings (as another pyarrow would): same fingerprint
    other = tmp_path / "other"
    other.mkdir()
    for name in (RECORDINGS_FILE, SAMPLES_FILE):
        pq.write_table(
            pq.read_table(tmp_path / "ds" / name),
            other / name,
            compression="zstd",
            use_dictionary=False,
            row_group_size=3,
            data_page_version="2.0",
            write_statistics=False,
        )
    assert read_dataset(other).fingerprint == ds.fingerprint
    # any change of content changes it
    changed = {"a": SAMPLES["a"].copy(), "b": SAMPLES["b"]}
    changed["a"][9, 1] += 1
    labels = {"a": np.ones(10, bool), "b": np.zeros(6, bool)}
    prints = {
        Dataset(_frame(), changed, labels).fingerprint,
        Dataset(
            _frame(), SAMPLES, {"a": np.ones(10, bool), "b": np.array([0, 0, 0, 0, 0, 1], bool)}
        ).fingerprint,
        Dataset(_frame(), SAMPLES).fingerprint,
        Dataset(_frame(source=["test", "other"]), SAMPLES, labels).fingerprint,
        Dataset(_frame(speed_mm_s=[5.0, 0.0]), SAMPLES, labels).fingerprint,
        ds.fingerprint,
    }
    assert len(prints) == 6


def test_in_memory_dataset_has_a_fingerprint():
    one, two = (Dataset(_frame(), {"a": SAMPLES["a"] * k, "b": SAMPLES["b"]}) for k in (1, 2))
    assert len(one.fingerprint) == 16 and one.fingerprint != two.fingerprint


# ----------------------------------------------------------------------------- baseline
def test_univariate_baseline_removes_channel_offsets():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(50, 3))
    offset = np.array([3000.0, -200.0, 50.0])
    assert not np.allclose(
        univariate(a), univariate(a + offset), atol=1e-3
    )  # the paper's s depends on offsets
    np.testing.assert_allclose(
        univariate(a + offset, baseline=10), univariate(a, baseline=10), atol=1e-4
    )
    start = a[:10].mean(axis=0)
    np.testing.assert_allclose(
        univariate(a, baseline=10), np.diff(np.linalg.norm(a - start, axis=1)), rtol=1e-5, atol=1e-6
    )
    np.testing.assert_array_equal(
        univariate(a, baseline=100), univariate(a - a.mean(axis=0))
    )  # shorter: all samples
    with pytest.raises(Exception, match="baseline must be an int >= 0"):
        univariate(a, baseline=-1)


# ----------------------------------------------------------------------------- broken files
@pytest.mark.parametrize(
    "name, mutate, message",
    [
        (
            SAMPLES_FILE,
            lambda t: t.drop_columns(["sample_index"]),
            r"column 'sample_index': required column missing",
        ),
        (
            RECORDINGS_FILE,
            lambda t: t.drop_columns(["sampling_rate_hz"]),
            r"column 'sampling_rate_hz': required column missing",
        ),
        (
            RECORDINGS_FILE,
            lambda t: t.set_column(0, "recording_id", pa.array(["a", "a"])),
            r"recording 'a': column 'recording_id': recording_id is not unique",
        ),
        (
            RECORDINGS_FILE,
            lambda t: t.set_column(6, "sampling_rate_hz", pa.array([1000.0, -1.0])),
            r"recording 'b': column 'sampling_rate_hz': sampling rate must be a finite positive number, got -1$",
        ),
        (
            RECORDINGS_FILE,
            lambda t: t.set_column(3, "scenario", pa.array(["slip", "poke"])),
            r"recording 'b': column 'scenario': scenario 'poke'",
        ),
        (
            RECORDINGS_FILE,
            lambda t: t.set_column(8, "units", pa.array([["N"], ["N", "N"]])),
            r"recording 'a': column 'units'",
        ),
        (
            SAMPLES_FILE,
            lambda t: t.set_column(
                2,
                "values",
                pa.array([[0.0, float("nan")]] + [[1.0, 1.0]] * 15, pa.list_(pa.float32())),
            ),
            r"recording 'a': column 'values': non-finite value .* sample_index 0",
        ),
        (
            SAMPLES_FILE,
            lambda t: t.set_column(
                1, "sample_index", pa.array(list(range(9)) + [10] + list(range(6)), pa.int64())
            ),
            r"recording 'a': column 'sample_index': sample_index 10 \(row 9\) is out of range",
        ),
        (
            SAMPLES_FILE,
            lambda t: t.set_column(
                1, "sample_index", pa.array(list(range(9)) + [3] + list(range(6)), pa.int64())
            ),
            r"recording 'a': column 'sample_index': sample_index 3 appears more than once",
        ),
        (
            SAMPLES_FILE,
            lambda t: t.set_column(
                2, "values", pa.array([[1.0]] + [[1.0, 1.0]] * 15, pa.list_(pa.float32()))
            ),
            r"recording 'a': column 'values': sample_index 0 \(row 0\) has 1 values but the recording has 2 channels",
        ),
        (
            SAMPLES_FILE,
            lambda t: t.take(list(range(10, 16)) + list(range(10)))[:6],
            r"recording 'a': column 'recording_id': recording has no samples",
        ),
        (
            SAMPLES_FILE,
            lambda t: t.set_column(2, "values", t.column("values").cast(pa.list_(pa.string()))),
            r"column 'values': must be a list of numbers",
        ),
        (
            SAMPLES_FILE,
            lambda t: t.set_column(3, "slip", pa.array([1] * 10 + [2] + [0] * 5, pa.int8())),
            r"recording 'b': column 'slip': .* sample_index 0 has 2",
        ),
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


def test_info_reports_slip_fraction_and_disagreement_with_the_scenario(tmp_path):
    from slipbench.app.info import info

    labels = {"a": np.array([1] * 6 + [0] * 4, np.int8), "b": np.array([0, 0, 0, 0, 0, 1], np.int8)}
    table = info(read_dataset(write_dataset(tmp_path / "d", _frame(), SAMPLES, labels))).set_index(
        "scenario"
    )
    assert table.loc["slip", "slip_fraction"] == pytest.approx(0.6)
    assert table.loc["slip", "scenario_disagreement"] == pytest.approx(
        0.4
    )  # stick phases of a slip recording
    assert table.loc["press", "scenario_disagreement"] == pytest.approx(1 / 6)
    assert "slip_fraction" not in info(
        read_dataset(write_dataset(tmp_path / "n", _frame(), SAMPLES))
    )
