"""The reader and writer under fire (issue 11's fault suite).

Property-based round trips (hypothesis, bounded examples) over the shapes labs have: rates from
60 Hz to 2.2 kHz with per-recording jitter inside a unit, 1-6 channels, integer, float32 and
float64 values, recordings of 2 samples, one class only, per-sample labels with nulls, hold-slip
recordings, trials shared by several recordings; written by `write_dataset`, rewritten with other
Arrow flavours, row orders and row groups, read back identical with an identical fingerprint.

Corruptions, each refused by `slipbench dataset validate` with exit code 2 and one line naming
the file (and the recording and column where there is one), never a traceback:

 1. samples.parquet missing                     21. a recording with one sample
 2. recordings.parquet not a Parquet file       22. a null sample_index
 3. samples.parquet truncated                   23. a negative sample_index
 4. no format version in the metadata           24. a repeated sample_index
 5. an unsupported format version               25. a sample_index beyond the recording (a gap)
 6. a required column missing                   26. a row with more values than channels
 7. a column of the wrong type                  27. a null list of values
 8. a null in a required column                 28. a null value inside a list
 9. an empty recording_id                       29. a NaN value
10. a duplicate recording_id                    30. an infinite value
11. an unknown scenario                         31. an integer beyond 2**53
12. a NaN sampling rate                         32. values that are strings
13. a negative speed                            33. a slip column of strings
14. an empty channel list                       34. a slip value of 2
15. fewer units than channels                   35. hold-slip without a slip column
16. a null channel name                         36. hold-slip with no sample held (no-slip)
17. a trial column of integers                  37. a samples file with no rows
18. a unit whose rates differ beyond 1 %        38. a recordings file with no rows
19. samples of an unlisted recording            39. a null recording_id in samples.parquet
20. a recording without samples                 40. a recording_id of another type (int)
                                                41. rows lost at a recording's end (n_samples)
                                                42. a column name that is not UTF-8 (a bit flip)
                                                43. a column name given twice

Property-based corruptions: a NaN at a random sample of a random recording is reported with that
recording and sample_index; any one row removed is reported with its recording (a row lost at a
recording's end shows against the `n_samples` that `write_dataset` records); any column name of
either file made invalid UTF-8, or given to a second column, is reported with the file and the
column's position.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from parquetfaults import name_not_utf8, name_twice

from slipbench.data.format import Dataset
from slipbench.data.read import read_dataset
from slipbench.data.schema import RATE_TOLERANCE, RECORDINGS_FILE, SAMPLES_FILE, VERSION_KEY
from slipbench.data.write import write_dataset
from slipbench.errors import DataError

SETTINGS = settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
#: the column-name faults fail at the footer, before any sample is read: fewer examples suffice
NAME_SETTINGS = settings(SETTINGS, max_examples=10)
RATES = (60.0, 100.0, 850.0, 1000.0, 2200.0)


# ----------------------------------------------------------------------------- shapes labs have
@st.composite
def lab_datasets(draw):
    """(recordings frame, samples, labels or None) shaped like a lab's recordings."""
    labelled = draw(st.sampled_from(["none", "all", "some"]))
    scenarios = ["slip", "press", "free-space"] + (["hold-slip"] if labelled != "none" else [])
    one_class = draw(st.booleans())
    kinds = draw(
        st.sampled_from([("int",), ("float32",), ("float64",), ("int", "float32", "float64")])
    )
    rows, samples, labels = [], {}, {}
    for u in range(draw(st.integers(1, 3))):
        n_ch = draw(st.integers(1, 6))
        rate = draw(st.sampled_from(RATES))
        for r in range(draw(st.integers(1, 4))):
            rid = draw(st.text("abcxyz-/_0123456789", min_size=1, max_size=6)) + f"#{u}.{r}"
            n = draw(st.integers(2, 40))
            kind = draw(st.sampled_from(kinds))
            scenario = "slip" if one_class else draw(st.sampled_from(scenarios))
            seed = draw(st.integers(0, 2**32 - 1))
            rng = np.random.default_rng(seed)
            if kind == "int":
                a = rng.integers(-5000, 5000, size=(n, n_ch))
            else:
                a = rng.normal(0, 100, size=(n, n_ch)).astype(kind)
            samples[rid] = a
            if (
                scenario == "hold-slip"
                or (labelled == "all")
                or (labelled == "some" and draw(st.booleans()))
            ):
                lab = rng.choice(np.array([-1, 0, 1], np.int8), size=n)
                if scenario == "hold-slip":
                    onset = draw(st.integers(1, n - 1))
                    lab[:onset] = np.where(lab[:onset] == 1, 0, lab[:onset])
                    lab[0], lab[onset] = 0, 1
                labels[rid] = lab
            rows.append(
                dict(
                    recording_id=rid,
                    sensor_type=f"T{u % 2}",
                    sensor_instance=f"unit{u}",
                    scenario=scenario,
                    material=draw(st.sampled_from([None, "PVC", "foam"])),
                    speed_mm_s=draw(st.sampled_from([None, 0.0, 5.0, 75.0])),
                    sampling_rate_hz=rate * (1 + draw(st.floats(0, RATE_TOLERANCE * 0.9))),
                    channels=tuple(f"c{i}" for i in range(n_ch)),
                    units=("count",) * n_ch,
                    source=draw(st.sampled_from([None, "lab"])),
                    trial=draw(st.sampled_from([None, "t1", "t2"])),
                )
            )
    return pd.DataFrame(rows), samples, (labels or None)


def _check_equal(ds: Dataset, rec: pd.DataFrame, samples: dict, labels: dict | None) -> None:
    assert list(ds.recordings["recording_id"]) == sorted(rec["recording_id"])
    by_id = rec.set_index("recording_id")
    for row in ds.recordings.itertuples(index=False):
        given_row = by_id.loc[row.recording_id]
        assert row.sampling_rate_hz == given_row["sampling_rate_hz"]
        assert row.trial == (
            row.recording_id if pd.isna(given_row["trial"]) else given_row["trial"]
        )
        assert row.channels == given_row["channels"] and row.scenario == given_row["scenario"]
    all_float32 = all(a.dtype == np.float32 for a in samples.values())
    for rid, a in samples.items():
        got = ds.samples[rid]
        assert got.dtype == (np.float32 if all_float32 else np.float64)
        np.testing.assert_array_equal(got, a)
        if labels is None:
            assert rid not in ds.slip_labels
        else:
            expected = labels.get(rid, np.full(len(a), -1, np.int8))
            np.testing.assert_array_equal(ds.slip_labels[rid], expected)
    unit_rates = ds.recordings.groupby(["sensor_type", "sensor_instance"])[
        "sampling_rate_hz"
    ].transform("median")
    np.testing.assert_array_equal(ds.recordings["unit_rate_hz"], unit_rates)


@SETTINGS
@given(lab_datasets())
def test_round_trip(tmp_path_factory, data):
    rec, samples, labels = data
    path = write_dataset(tmp_path_factory.mktemp("rt") / "ds", rec, samples, labels)
    ds = read_dataset(path)
    _check_equal(ds, rec, samples, labels)
    assert ds.fingerprint == Dataset(rec, samples, labels or {}).fingerprint


def _flavours(table: pa.Table, rng: np.random.Generator) -> pa.Table:
    """The same table with other string/list flavours and its rows shuffled."""
    out = table.take(rng.permutation(table.num_rows))
    for i, f in enumerate(out.schema):
        column = out.column(i)
        if pa.types.is_dictionary(f.type) or pa.types.is_string(f.type):
            column = column.cast(pa.string()).cast(
                rng.choice([pa.large_string(), pa.string_view(), pa.string()])
            )
        elif pa.types.is_list(f.type) or pa.types.is_large_list(f.type):
            column = column.cast(
                (pa.list_ if rng.random() < 0.5 else pa.large_list)(f.type.value_type)
            )
        out = out.set_column(i, f.name, column)
    return out


@pytest.mark.slow
@SETTINGS
@given(lab_datasets(), st.integers(0, 2**32 - 1), st.integers(1, 50))
def test_any_row_order_and_flavour_reads_the_same(tmp_path_factory, data, seed, row_group):
    rec, samples, labels = data
    root = tmp_path_factory.mktemp("rw")
    reference = read_dataset(write_dataset(root / "ref", rec, samples, labels))
    other = root / "other"
    other.mkdir()
    rng = np.random.default_rng(seed)
    for name in (RECORDINGS_FILE, SAMPLES_FILE):
        table = pq.read_table(root / "ref" / name)
        pq.write_table(
            _flavours(table, rng).replace_schema_metadata(table.schema.metadata),
            other / name,
            row_group_size=row_group,
        )
    ds = read_dataset(other)
    _check_equal(ds, rec, samples, labels)
    assert ds.fingerprint == reference.fingerprint


@SETTINGS
@given(lab_datasets(), st.data())
def test_a_nan_anywhere_is_named(tmp_path_factory, data, pick):
    rec, samples, labels = data
    samples = {k: v.astype(np.float64) for k, v in samples.items()}
    path = write_dataset(tmp_path_factory.mktemp("nan") / "ds", rec, samples, labels)
    rid = pick.draw(st.sampled_from(sorted(samples)))
    row = pick.draw(st.integers(0, len(samples[rid]) - 1))
    channel = pick.draw(st.integers(0, samples[rid].shape[1] - 1))
    table = pq.read_table(path / SAMPLES_FILE)
    rids = table.column("recording_id").cast(pa.string()).to_pylist()
    index = table.column("sample_index").to_pylist()
    values = table.column("values").to_pylist()
    values[next(i for i, (r, s) in enumerate(zip(rids, index)) if r == rid and s == row)][
        channel
    ] = float("nan")
    table = table.set_column(2, "values", pa.array(values, pa.large_list(pa.float64())))
    pq.write_table(table, path / SAMPLES_FILE)
    with pytest.raises(Exception) as err:
        read_dataset(path)
    assert err.type.__name__ == "DataError"
    assert (
        f"recording {rid!r}: column 'values': non-finite value (NaN or infinity) at sample_index {row}"
        in str(err.value)
    )


@SETTINGS
@given(lab_datasets(), st.data())
def test_a_missing_row_is_named(tmp_path_factory, data, pick):
    rec, samples, labels = data
    path = write_dataset(tmp_path_factory.mktemp("gap") / "ds", rec, samples, labels)
    table = pq.read_table(path / SAMPLES_FILE)
    drop = pick.draw(st.integers(0, table.num_rows - 1))
    rid = table.column("recording_id").cast(pa.string())[drop].as_py()
    pq.write_table(table.take([i for i in range(table.num_rows) if i != drop]), path / SAMPLES_FILE)
    with pytest.raises(Exception) as err:
        read_dataset(path)
    assert (
        err.type.__name__ == "DataError"
        and f"recording {rid!r}" in str(err.value)
        and SAMPLES_FILE in str(err.value)
    )


def _one_file(tmp_path_factory, data, pick) -> tuple[Path, Path]:
    """A written lab dataset, and one of its two files, drawn."""
    path = write_dataset(tmp_path_factory.mktemp("names") / "ds", *data)
    return path, path / pick.draw(st.sampled_from([RECORDINGS_FILE, SAMPLES_FILE]))


@NAME_SETTINGS
@given(lab_datasets(), st.data())
def test_a_column_name_not_utf8_is_named_by_position(tmp_path_factory, data, pick):
    path, file = _one_file(tmp_path_factory, data, pick)
    names = pq.read_schema(file).names
    k = pick.draw(st.integers(0, len(names) - 1))
    file.write_bytes(name_not_utf8(file.read_bytes(), names[k]))
    with pytest.raises(DataError) as err:
        read_dataset(path)
    after = f" (after {names[k - 1]!r})" if k else ""
    assert str(err.value).startswith(
        f"{file}: column {k + 1} of {len(names)}{after}: its name is not valid UTF-8"
    ), err.value


@NAME_SETTINGS
@given(lab_datasets(), st.data())
def test_a_column_name_given_twice_is_named_by_position(tmp_path_factory, data, pick):
    path, file = _one_file(tmp_path_factory, data, pick)
    table = pq.read_table(file)
    keep, rename = pick.draw(
        st.lists(st.integers(0, table.num_columns - 1), min_size=2, max_size=2, unique=True)
    )
    pq.write_table(name_twice(table, keep, rename), file)
    with pytest.raises(DataError) as err:
        read_dataset(path)
    first, second = sorted((keep, rename))
    assert str(err.value).startswith(
        f"{file}: columns {first + 1} and {second + 1} of {table.num_columns} are both named "
        f"{table.column_names[keep]!r}"
    ), err.value


# ----------------------------------------------------------------------------- corruptions
def _tiny(root):
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
            "trial": ["t", "t"],
        }
    )
    samples = {"a": np.arange(20, dtype=np.float64).reshape(10, 2), "b": np.ones((6, 2))}
    return write_dataset(
        root / "ds", rec, samples, {"a": np.ones(10, bool), "b": np.zeros(6, bool)}
    )


def _table(path, name, mutate, keep_meta=True):
    table = pq.read_table(path / name)
    meta = table.schema.metadata
    table = mutate(table)
    pq.write_table(table.replace_schema_metadata(meta if keep_meta else None), path / name)


def _col(name, values, type_=None):
    def mutate(t):
        return t.set_column(t.schema.get_field_index(name), name, pa.array(values, type_))

    return mutate


R, S = RECORDINGS_FILE, SAMPLES_FILE
VALUES = [[float(i), float(i + 1)] for i in range(16)]


def _values(change):
    rows = [list(v) for v in VALUES]
    return change(rows) or rows


CORRUPTIONS = {
    "samples file missing": (lambda p: (p / S).unlink(), S, None, None),
    "not a Parquet file": (
        lambda p: (p / R).write_bytes(b"recording_id,scenario\na,slip\n"),
        R,
        None,
        None,
    ),
    "truncated file": (
        lambda p: (p / S).write_bytes((p / S).read_bytes()[: (p / S).stat().st_size // 2]),
        S,
        None,
        None,
    ),
    "no format version": (lambda p: _table(p, R, lambda t: t, keep_meta=False), R, None, None),
    "unsupported version": (
        lambda p: pq.write_table(
            pq.read_table(p / S).replace_schema_metadata({VERSION_KEY: b"2"}), p / S
        ),
        S,
        None,
        None,
    ),
    "column missing": (
        lambda p: _table(p, R, lambda t: t.drop_columns(["sensor_type"])),
        R,
        None,
        "sensor_type",
    ),
    "wrong type": (
        lambda p: _table(p, R, _col("sampling_rate_hz", ["1000", "1000"])),
        R,
        None,
        "sampling_rate_hz",
    ),
    "null required": (
        lambda p: _table(p, R, _col("sensor_instance", ["index", None])),
        R,
        "b",
        "sensor_instance",
    ),
    "empty recording_id": (
        lambda p: _table(p, R, _col("recording_id", ["a", ""])),
        R,
        None,
        "recording_id",
    ),
    "duplicate recording_id": (
        lambda p: _table(p, R, _col("recording_id", ["a", "a"])),
        R,
        "a",
        "recording_id",
    ),
    "unknown scenario": (
        lambda p: _table(p, R, _col("scenario", ["slip", "poke"])),
        R,
        "b",
        "scenario",
    ),
    "NaN rate": (
        lambda p: _table(p, R, _col("sampling_rate_hz", [1000.0, float("nan")])),
        R,
        "b",
        "sampling_rate_hz",
    ),
    "negative speed": (
        lambda p: _table(p, R, _col("speed_mm_s", [-5.0, None])),
        R,
        "a",
        "speed_mm_s",
    ),
    "empty channels": (
        lambda p: _table(p, R, _col("channels", [[], ["x", "y"]])),
        R,
        "a",
        "channels",
    ),
    "fewer units": (lambda p: _table(p, R, _col("units", [["N"], ["N", "N"]])), R, "a", "units"),
    "null channel name": (
        lambda p: _table(p, R, _col("channels", [["x", None], ["x", "y"]])),
        R,
        "a",
        "channels",
    ),
    "integer trial": (lambda p: _table(p, R, _col("trial", [1, 2])), R, None, "trial"),
    "rates beyond tolerance": (
        lambda p: _table(p, R, _col("sampling_rate_hz", [1000.0, 1100.0])),
        R,
        None,
        "sampling_rate_hz",
    ),
    "unlisted recording": (
        lambda p: _table(p, S, _col("recording_id", ["a"] * 10 + ["c"] * 6)),
        S,
        "c",
        "recording_id",
    ),
    "recording without samples": (
        lambda p: _table(p, S, lambda t: t.slice(0, 10)),
        S,
        "b",
        "recording_id",
    ),
    "one sample": (lambda p: _table(p, S, lambda t: t.slice(0, 11)), S, "b", "sample_index"),
    "null sample_index": (
        lambda p: _table(
            p,
            S,
            _col("sample_index", [0, 1, None] + list(range(3, 10)) + list(range(6)), pa.int64()),
        ),
        S,
        "a",
        "sample_index",
    ),
    "negative sample_index": (
        lambda p: _table(
            p, S, _col("sample_index", [-1] + list(range(1, 10)) + list(range(6)), pa.int64())
        ),
        S,
        "a",
        "sample_index",
    ),
    "repeated sample_index": (
        lambda p: _table(
            p, S, _col("sample_index", list(range(10)) + [0, 1, 2, 2, 4, 5], pa.int64())
        ),
        S,
        "b",
        "sample_index",
    ),
    "gap in sample_index": (
        lambda p: _table(
            p, S, _col("sample_index", list(range(10)) + [0, 1, 2, 3, 4, 6], pa.int64())
        ),
        S,
        "b",
        "sample_index",
    ),
    "row too wide": (
        lambda p: _table(
            p, S, _col("values", _values(lambda v: v[12].append(1.0)), pa.list_(pa.float64()))
        ),
        S,
        "b",
        "values",
    ),
    "null list": (
        lambda p: _table(
            p, S, _col("values", _values(lambda v: v.__setitem__(3, None)), pa.list_(pa.float64()))
        ),
        S,
        "a",
        "values",
    ),
    "null in list": (
        lambda p: _table(
            p,
            S,
            _col("values", _values(lambda v: v[3].__setitem__(1, None)), pa.list_(pa.float64())),
        ),
        S,
        "a",
        "values",
    ),
    "NaN value": (
        lambda p: _table(
            p,
            S,
            _col(
                "values",
                _values(lambda v: v[14].__setitem__(0, float("nan"))),
                pa.list_(pa.float64()),
            ),
        ),
        S,
        "b",
        "values",
    ),
    "infinite value": (
        lambda p: _table(
            p,
            S,
            _col(
                "values",
                _values(lambda v: v[0].__setitem__(0, float("-inf"))),
                pa.list_(pa.float64()),
            ),
        ),
        S,
        "a",
        "values",
    ),
    "integer beyond 2**53": (
        lambda p: _table(p, S, _col("values", [[2**60, 1]] + [[1, 1]] * 15, pa.list_(pa.int64()))),
        S,
        "a",
        "values",
    ),
    "string values": (
        lambda p: _table(p, S, _col("values", [["1", "2"]] * 16, pa.list_(pa.string()))),
        S,
        None,
        "values",
    ),
    "string slip": (lambda p: _table(p, S, _col("slip", ["yes"] * 16)), S, None, "slip"),
    "slip of 2": (
        lambda p: _table(p, S, _col("slip", [1] * 9 + [2] + [0] * 6, pa.int8())),
        S,
        "a",
        "slip",
    ),
    "hold-slip without labels": (
        lambda p: (
            _table(p, R, _col("scenario", ["hold-slip", "press"])),
            _table(p, S, lambda t: t.drop_columns(["slip"])),
        ),
        S,
        "a",
        "slip",
    ),
    "hold-slip without a hold": (
        lambda p: (
            _table(p, R, _col("scenario", ["press", "hold-slip"])),
            _table(p, S, _col("slip", [0] * 10 + [1] * 6, pa.int8())),
        ),
        S,
        "b",
        "slip",
    ),
    "no rows": (lambda p: _table(p, S, lambda t: t.slice(0, 0)), S, None, None),
    "no recordings": (lambda p: _table(p, R, lambda t: t.slice(0, 0)), R, None, None),
    "null recording_id": (
        lambda p: _table(p, S, _col("recording_id", ["a"] * 10 + [None] + ["b"] * 5)),
        S,
        None,
        "recording_id",
    ),
    "integer recording_id": (
        lambda p: _table(p, S, _col("recording_id", [1] * 10 + [2] * 6)),
        S,
        None,
        "recording_id",
    ),
    "rows lost at the end": (
        lambda p: _table(p, S, lambda t: t.slice(0, 15)),
        S,
        "b",
        "sample_index",
    ),
    "column name not UTF-8": (
        lambda p: (p / R).write_bytes(name_not_utf8((p / R).read_bytes(), "scenario")),
        R,
        None,
        None,
    ),
    "column name twice": (lambda p: _table(p, S, lambda t: name_twice(t, 1, 2)), S, None, None),
}


@pytest.mark.parametrize("kind", sorted(CORRUPTIONS))
def test_corruption_is_refused_with_exit_2(tmp_path, cli, kind):
    corrupt, file, recording, column = CORRUPTIONS[kind]
    path = _tiny(tmp_path)
    corrupt(path)
    code, out, err = cli(["dataset", "validate", str(path)])
    assert code == 2, (kind, out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in err, err
    assert str(path / file) in lines[0], err
    if recording is not None:
        assert f"recording {recording!r}" in lines[0], err
    if column is not None:
        assert f"column {column!r}" in lines[0], err
    assert not re.search(r"np\.(float|int|str)", lines[0]), err


def test_at_least_fifteen_kinds():
    assert len(CORRUPTIONS) >= 15


@pytest.mark.slow
def test_validate_in_a_separate_process_prints_no_traceback(tmp_path):
    """The installed command, not the in-process one: stderr holds one line, exit code 2."""
    import subprocess
    import sys

    path = _tiny(tmp_path)
    CORRUPTIONS["NaN value"][0](path)
    done = subprocess.run(
        [sys.executable, "-m", "slipbench.app.cli", "dataset", "validate", str(path)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert (
        done.returncode == 2 and done.stderr.count("\n") == 1 and "Traceback" not in done.stderr
    ), done.stderr
    shutil.rmtree(path)
