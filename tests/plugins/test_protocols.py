"""What each protocol trains and tests on, pinned on the simulated data."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from datagen import subset

from slipbench.data.format import Dataset
from slipbench.data.signals import Signals
from slipbench.engine.plan import CellData
from slipbench.protocol import window_cells
from slipbench.protocols.cross_instance import CrossInstance
from slipbench.protocols.material_holdout import MaterialHoldout
from slipbench.protocols.sampling_rate import SamplingRate
from slipbench.protocols.speed_holdout import SpeedHoldout
from slipbench.protocols.window_size import WindowSize
from slipbench.vocabulary import SLIPS


@pytest.fixture(scope="module")
def nano(small):
    return subset(small, small.recordings["sensor_type"].eq("Nano17"))


def _data(ds, protocol, how="paper"):
    signals = Signals.from_dataset(ds)
    for name, values in protocol.columns(ds.recordings).items():
        signals.recordings[name] = values
    return CellData(signals, how, seed=0)


def _windows(data, cell, part):
    return data.values(data.part(part, cell.window), cell)


def test_window_size_cells(small):
    cells = list(WindowSize().cells(small.recordings))
    assert len(cells) == 8 * 6
    assert {c.window for c in cells} == {5, 10, 25, 50, 100, 200}
    assert all(c.train.sensors == c.test.sensors and len(c.train.sensors) == 1 for c in cells)


def test_material_holdout_never_trains_on_the_held_out_material(nano):
    protocol = MaterialHoldout()
    data = _data(nano, protocol)
    cells = list(protocol.cells(nano.recordings))
    assert len(cells) == 3 * 5 * 2
    for cell in cells:
        material = cell.key["material"]
        train, test = _windows(data, cell, cell.train), _windows(data, cell, cell.test)
        assert set(test.column("material")) == {material}
        assert set(test.column("scenario")) == {"slip", "press"}
        trained_on = set(pd.Series(train.column("material")).dropna())
        if cell.key["training"] == "without":
            assert material not in trained_on and "free-space" in set(train.column("scenario"))
        else:
            assert material in trained_on
    # the "with" model is the window-size model at window 50: same train part
    with_cell = next(c for c in cells if c.key["training"] == "with")
    ws = next(
        c
        for c in WindowSize().cells(nano.recordings)
        if c.window == 50 and c.train == with_cell.train
    )
    assert ws.train == with_cell.train and ws.window == with_cell.window


def test_a_hold_slip_trial_that_never_slips_is_no_slip_recording():
    """A hold-slip trial that held throughout was never slipping at its speed: the reader marks
    it as not slipping, and the speed holdout neither holds its speed out nor counts it."""
    rows, samples, labels = [], {}, {}
    for i, (speed, slips) in enumerate([(25.0, True), (25.0, False), (50.0, False)]):
        rid = f"trial{i}"
        rows.append(
            dict(
                recording_id=rid,
                sensor_type="Skin",
                sensor_instance="pad",
                scenario="hold-slip",
                material="felt",
                speed_mm_s=speed,
                sampling_rate_hz=100.0,
                channels=("c",),
                units=("raw",),
                source="lab",
                trial=rid,
            )
        )
        samples[rid] = np.random.default_rng(i).normal(size=(200, 1))
        labels[rid] = np.r_[np.zeros(100), np.full(100, int(slips))].astype(np.int8)
    recordings = Dataset(pd.DataFrame(rows), samples, labels).recordings
    assert list(recordings[SLIPS]) == [True, False, False]
    assert SpeedHoldout().levels(recordings) == [25.0]
    unknown = recordings.assign(speed_mm_s=np.nan)
    assert "none of its 1 slip recordings gives a speed" in SpeedHoldout().why_no_cells(unknown)
    held = recordings[~recordings[SLIPS]]
    assert "no recording slips" in SpeedHoldout().why_no_cells(held)


def test_speed_holdout_assigns_pressing_and_holds_out_speeds(nano):
    protocol = SpeedHoldout()
    group = protocol.columns(nano.recordings)["speed_group"]
    rec = nano.recordings.assign(group=group)
    press = rec[rec["scenario"] == "press"]
    assert set(press["group"]) == {5.0, 25.0, 50.0, 75.0}
    time = (
        press.groupby(["sensor_instance", "material", "group"])["n_samples"]
        .sum()
        .groupby(["sensor_instance", "material"])
    )
    assert (
        (time.max() - time.min()) <= press["n_samples"].max()
    ).all()  # equal time, to within one recording
    data = _data(nano, protocol)
    for cell in protocol.cells(nano.recordings):
        speed = cell.key["speed_mm_s"]
        train, test = _windows(data, cell, cell.train), _windows(data, cell, cell.test)
        scenario = test.column("scenario")
        assert set(test.column("speed_group")) == {speed}
        assert set(scenario) == (
            {"slip", "press"} if speed == 5 else {"slip", "press", "free-space"}
        )
        train_speeds = set(pd.Series(train.column("speed_mm_s")).dropna())
        if cell.key["training"] == "without":
            assert speed not in train_speeds and "press" in set(train.column("scenario"))
        else:
            assert speed in train_speeds


def test_cross_instance_cells(small):
    cells = list(CrossInstance().cells(small.recordings))
    assert len(cells) == 4 * 4 + 4 * 4 + 3 * 3
    combined = next(
        c
        for c in cells
        if c.key
        == {"sensor_type": "Nano17", "train_instance": "combined", "test_instance": "index"}
    )
    assert len(combined.train.sensors) == 3 and combined.test.sensors == (("Nano17", "index"),)
    assert not any(c.skip for c in cells)


def test_cross_instance_skips_a_type_with_one_instance(small):
    one = subset(small, small.recordings["sensor_instance"].eq("index"))
    cells = list(CrossInstance().cells(one.recordings))
    skipped = [c for c in cells if c.skip]
    assert skipped and all("has one instance" in c.skip for c in skipped)
    assert all(
        c.key["train_instance"] == c.key["test_instance"] != "combined" for c in cells if not c.skip
    )


def test_sampling_rate_cells(nano):
    cells = [
        c for c in SamplingRate().cells(nano.recordings) if c.key["sensor_instance"] == "index"
    ]
    assert [c.key["rate_hz"] for c in cells] == [1000, 500, 250, 125, 62.5, 31.25]
    assert {(c.decimation, c.antialias) for c in cells} == {
        ("plain", False)
    }  # the default; tests/data/test_decimation.py has the rest


@pytest.mark.parametrize(
    "protocol, message",
    [
        (
            SamplingRate(decimation="cubic"),
            "The 'decimation' parameter of SamplingRate must be one of 'plain'",
        ),
        (
            WindowSize(windows="abc"),
            "The 'windows' parameter of WindowSize must be an int number of samples in \\[5, 10000000\\], or milliseconds",
        ),
        (WindowSize(windows=[50, "20ms"]), "takes samples or milliseconds, not both"),
        (MaterialHoldout(window=2), "The 'window' parameter of MaterialHoldout must be"),
        (CrossInstance(window=50.5), "The 'window' parameter of CrossInstance must be"),
    ],
)
def test_protocol_options_are_validated(protocol, message):
    from slipbench.errors import UsageError

    with pytest.raises(UsageError, match=message):
        protocol.validate_params()


def test_windows_in_milliseconds_convert_per_sensor(small):
    cells = [c for c in WindowSize(windows=["50ms", "5ms"]).cells(small.recordings)]
    by = {
        (c.key["sensor_type"], c.key["window_ms"]): c
        for c in cells
        if c.key["sensor_instance"] == "index"
    }
    assert by["Nano17", 50.0].window == 50 and by["BioTacSP", 50.0].window == 42  # 850 Hz
    assert (
        by["BioTacSP", 5.0].skip == "5ms is 4 samples at 850 Hz; a window needs at least 5 samples"
    )
    assert not by["Nano17", 5.0].skip
    assert (
        WindowSize(windows=["50ms"]).layout.column == "window_ms"
        and WindowSize().layout.column == "window"
    )
    fast = small.recordings.assign(unit_rate_hz=1e6)  # an hour at 1 MHz: 3.6e9 samples
    (_, key, skip), *_ = window_cells(fast, ("Nano17", "index"), "3600000ms")
    assert key["window"] == 3_600_000_000 and skip.endswith(
        "a window needs at most 10000000 samples"
    )
