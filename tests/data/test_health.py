"""A dataset's health, said with figures: rows a slow sensor's logger repeated, time gaps and a
wandering rate where the import had a time column; and the import's routes for them
(``[rate] drop_repeats``, ``resample_hz``), which the rate refusal names."""

from __future__ import annotations

import json

import numpy as np
import pytest
from labshapes import LOG_MAPPING, repeated_rows, slow_sensor_logs

from slipbench.data.health import repeats
from slipbench.data.importers import import_csv
from slipbench.data.read import read_dataset, read_description
from slipbench.errors import DataError, UsageError

REPEATED = (
    "warning: sensor Pad unit left: 75.8 % of its samples repeat the one before in every "
    "channel (225 of 297; longest run 4 samples), so s_t is 0 there: it updates at about "
    "9.7 Hz, logged at 40 Hz; import with [rate] drop_repeats = true"
)


def test_repeats_count_rows_equal_in_every_channel_and_the_longest_run():
    a = np.array([[1, 2], [1, 2], [1, 2], [1, 3], [1, 3], [2, 3]])
    assert repeats(a) == (3, 3)
    assert repeats(np.arange(6).reshape(3, 2)) == (0, 1)


@pytest.mark.parametrize(
    "command", [["validate"], ["info"], ["check", "--protocol", "window-size"]]
)
def test_repeated_rows_are_said_by_validate_info_and_check(tmp_path, cli, command):
    ds = repeated_rows(tmp_path)  # a 10 Hz sensor logged at 40 Hz
    code, out, err = cli(["dataset", *command, str(ds.path)])
    assert code == 0, err
    assert REPEATED in out


def test_a_jittery_logger_is_refused_naming_the_routes_then_resampled(tmp_path):
    slow_sensor_logs(tmp_path / "src", logger_hz=(32.0, 46.0))  # 31.9-46 Hz, a 10 Hz sensor
    with pytest.raises(
        DataError,
        match=r"give each its own sensor_instance\); a logger whose "
        r"rate wanders is one: import it with \[rate\] resample_hz = .*drop_repeats",
    ):
        import_csv(tmp_path / "src", tmp_path / "no", LOG_MAPPING | {"rate": {"time_column": "t"}})
    rate = {"time_column": "t", "drop_repeats": True, "resample_hz": 10.0}
    ds = read_dataset(import_csv(tmp_path / "src", tmp_path / "out", LOG_MAPPING | {"rate": rate}))
    assert set(ds.recordings["sampling_rate_hz"]) == {10.0}
    n = {len(s) for s in ds.samples.values()}
    assert min(n) >= 50 and max(n) <= 80  # 240 rows over 5.2-7.5 s, at 10 Hz
    # labels follow their rows: hold, then slip
    for lab in ds.slip_labels.values():
        assert lab[0] == 0 and lab[-1] == 1 and (np.diff(lab) >= 0).all()
    # what the times showed is kept, and not said again once resampled
    timing = json.loads(read_description(ds.path)["slipbench.timing"])
    assert timing["resampled_hz"] == 10.0 and timing["rate_hz"][0] < 32 < 46 < timing["rate_hz"][2]


def test_time_gaps_and_rate_jitter_are_said(tmp_path, cli):
    slow_sensor_logs(tmp_path / "src", hold=1, logger_hz=(38.0, 41.0), gaps=3)
    # the rate stated (the files' own would be refused): their times are only looked at
    mapping = LOG_MAPPING | {"rate": {"time_column": "t", "hz": 40.0}}
    out_path = import_csv(tmp_path / "src", tmp_path / "out", mapping)
    code, out, err = cli(["dataset", "validate", str(out_path)])
    assert code == 0, err
    (gaps,) = [line for line in out.splitlines() if line.startswith("warning: time gaps")]
    assert gaps.startswith(
        "warning: time gaps: 18 steps over 1.5 x the median step in 6 of 6 files"
    )
    (jitter,) = [line for line in out.splitlines() if line.startswith("warning: rate jitter")]
    assert "run 38-41 Hz (median 39.5 Hz)" in jitter
    assert "repeat the one before" not in out  # hold 1: a sensor as fast as its logger


def test_dropping_repeats_keeps_one_row_per_reading(tmp_path):
    slow_sensor_logs(tmp_path / "src", files=2)
    mapping = LOG_MAPPING | {"rate": {"time_column": "t", "hz": 10.0, "drop_repeats": True}}
    ds = read_dataset(import_csv(tmp_path / "src", tmp_path / "out", mapping))
    for rid, samples in ds.samples.items():
        assert repeats(samples)[0] == 0 and 55 <= len(samples) <= 60  # 240 rows, 4 per reading
        assert len(ds.slip_labels[rid]) == len(samples)
    assert set(ds.recordings["sampling_rate_hz"]) == {10.0}


@pytest.mark.parametrize(
    "rate, message",
    [
        ({"hz": 40.0, "resample_hz": 10.0}, r"\[rate\].resample_hz needs a time_column"),
        (
            {"time_column": "t", "drop_repeats": "yes"},
            r"\[rate\].drop_repeats must be true or false",
        ),
        ({"time_column": "t", "resample_hz": 0}, r"\[rate\].resample_hz must be a number > 0"),
    ],
)
def test_bad_rate_options_are_named(tmp_path, rate, message):
    slow_sensor_logs(tmp_path / "src", files=1)
    with pytest.raises(UsageError, match=message):
        import_csv(tmp_path / "src", tmp_path / "out", LOG_MAPPING | {"rate": rate})
