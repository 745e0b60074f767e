"""A dataset's health, said with figures: rows a slow sensor's logger repeated, time gaps and a
wandering rate where the import had a time column; and the import's routes for them
(``[rate] drop_repeats``, ``resample_hz``), which the rate refusal names."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from labshapes import LATE_MAPPING, LOG_MAPPING, late_logs, repeated_rows, slow_sensor_logs

from slipbench.data.health import health_lines, repeats
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
    (stated,) = [line for line in out.splitlines() if line.startswith("warning: stated rate")]
    assert stated.startswith(  # 40 Hz stated; the 38 Hz files' rows over their times (gaps)
        "warning: stated rate: 3 of 6 files state 40 Hz, but their rows over their time "
        "columns come to 37.09-37.14 Hz; the stated rate is used"
    )
    assert "uneven steps" not in out  # 3 % jitter on each step: 5-95 % within 25 % of the median
    assert "repeat the one before" not in out  # hold 1: a sensor as fast as its logger


def test_dropping_repeats_keeps_one_row_per_reading(tmp_path):
    slow_sensor_logs(tmp_path / "src", files=2)
    mapping = LOG_MAPPING | {"rate": {"time_column": "t", "hz": 10.0, "drop_repeats": True}}
    ds = read_dataset(import_csv(tmp_path / "src", tmp_path / "out", mapping))
    for rid, samples in ds.samples.items():
        assert repeats(samples)[0] == 0 and 55 <= len(samples) <= 60  # 240 rows, 4 per reading
        assert len(ds.slip_labels[rid]) == len(samples)
    assert set(ds.recordings["sampling_rate_hz"]) == {10.0}
    # 10 Hz stated for the sensor, its logger's times at 40 Hz: not a disagreement
    assert "stated_off" not in json.loads(read_description(ds.path)["slipbench.timing"])
    # every row dropped is counted, and said with the dataset
    dropped = sum(240 - len(v) for v in ds.samples.values())
    (line,) = [x for x in health_lines(ds, read_description(ds.path)) if "dropped" in x]
    assert line.startswith(
        f"repeated rows dropped: [rate] drop_repeats = true dropped {dropped} of 480 rows "
        f"({100 * dropped / 480:.1f} %) in 2 files (most 7"
    )


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


# ----------------------------------------------------------------------------- trials that start in slip
LEADING = (
    "warning: leading slip: 2 of 12 hold-slip files started in slip; [labels] leading_slip = "
    "'trim' dropped their rows before the first no-slip sample: 11 rows (1.1 s) in all, most 7 "
    "in imu_08.csv"
)


def _late(labels: dict) -> dict:
    return LATE_MAPPING | {"labels": LATE_MAPPING["labels"] | labels}


def test_a_trial_that_starts_in_slip_is_refused_naming_the_route(tmp_path):
    late_logs(tmp_path / "src")
    with pytest.raises(
        DataError,
        match=r"imu_03.csv: scenario hold-slip: the trial starts in slip \(4 rows before its "
        r'first no-slip sample\): \[labels\] leading_slip = "trim" drops those rows, '
        r'"unlabelled" keeps them unlabelled',
    ):
        import_csv(tmp_path / "src", tmp_path / "no", LATE_MAPPING)
    assert not (tmp_path / "no").exists()
    with pytest.raises(UsageError, match=r"\[labels\].leading_slip must be one of refuse, trim"):
        import_csv(tmp_path / "src", tmp_path / "no", _late({"leading_slip": "cut"}))


def test_trimming_the_leading_slip_drops_those_rows_and_counts_them(tmp_path, cli):
    late_logs(tmp_path / "src")
    ds = read_dataset(
        import_csv(tmp_path / "src", tmp_path / "out", _late({"leading_slip": "trim"}))
    )
    n = {rid: len(s) for rid, s in ds.samples.items()}
    assert n["imu_03"] == 60 - 4 and n["imu_08"] == 60 - 7 and n["imu_00"] == 60
    raw = pd.read_csv(tmp_path / "src" / "imu_08.csv")
    np.testing.assert_array_equal(ds.samples["imu_08"][:, 0], raw["ax"].to_numpy()[7:])
    for rid, lab in ds.slip_labels.items():  # each holds first, its later slips kept
        assert lab[0] == 0 and lab.tolist().count(1) == 28, rid
    config = tmp_path / "late.toml"  # the same through the command: said on import, kept
    config.write_text(
        'files = ["*.csv"]\n[recording]\nsensor_type = "IMU"\nsensor_instance = "index"\n'
        'scenario = "hold-slip"\n[channels]\nnames = ["ax", "ay", "az"]\n[rate]\nhz = 10.0\n'
        '[labels]\ncolumn = "state"\nslip = ["slip"]\nno_slip = ["hold"]\nleading_slip = "trim"\n'
    )
    folder = str(tmp_path / "cli")
    for command in (
        ["import", "csv", str(tmp_path / "src"), folder, "--config", str(config)],
        ["validate", folder],
        ["info", folder],
        ["check", folder, "--protocol", "window-size", "--labels", "majority"],
    ):
        code, out, err = cli(["dataset", *command])
        assert code == 0, err
        assert LEADING in out, (command, out)


def test_a_leading_slip_kept_unlabelled_keeps_its_rows(tmp_path):
    late_logs(tmp_path / "src")
    out = import_csv(tmp_path / "src", tmp_path / "out", _late({"leading_slip": "unlabelled"}))
    ds = read_dataset(out)
    lab = ds.slip_labels["imu_08"]
    assert len(lab) == 60 and lab[:7].tolist() == [-1] * 7 and lab[7] == 0
    assert (ds.slip_labels["imu_00"] >= 0).all()  # a trial that holds first is untouched
    summary = json.loads(read_description(out)["slipbench.leading_slip"])
    assert summary["routes"] == ["unlabelled"] and summary["rows"] == 11
    assert summary["files"] == 2 and summary["hold_slip_files"] == 12


def test_a_rule_sets_the_route_for_its_files_only(tmp_path):
    late_logs(tmp_path / "src")
    rule = {"rules": [{"glob": "imu_0[38].csv", "leading_slip": "trim"}]}
    ds = read_dataset(import_csv(tmp_path / "src", tmp_path / "out", LATE_MAPPING | rule))
    assert len(ds.samples["imu_03"]) == 56
    late_logs(tmp_path / "src2", late={3: 4, 9: 2})  # imu_09 is not the rule's: refused
    with pytest.raises(
        DataError, match=r"imu_09.csv: scenario hold-slip: the trial starts in slip"
    ):
        import_csv(tmp_path / "src2", tmp_path / "no", LATE_MAPPING | rule)
