"""`dataset check` and the stand-in of a protocol that makes no cell: every protocol is named
with its reason, and the tables hold the windows the protocols use, once each."""

from __future__ import annotations

import numpy as np
import pandas as pd
from labshapes import bursty_labels
from test_outside_data import _recording, hundred_hz

from slipbench.data.read import read_dataset
from slipbench.data.write import write_dataset
from slipbench.engine.check import UNIT_COLUMNS, WINDOW_COLUMNS, check_dataset
from slipbench.engine.plan import Run
from slipbench.protocol import NO_CELL
from slipbench.protocols.speed_holdout import SpeedHoldout
from slipbench.protocols.streaming import Streaming
from slipbench.protocols.window_size import WindowSize


def two_rates(folder):
    """Two units at 100 and 250 Hz, slip and pressing, no material and no speed."""
    rng = np.random.default_rng(5)
    rows, samples = [], {}
    for unit, rate in ((("A", "one"), 100.0), (("B", "two"), 250.0)):
        for k in range(4):
            for scenario in ("slip", "press"):
                x = rng.normal(0, 1, (int(rate * 4), 3))
                rid = f"{unit[0]}-{scenario}-{k}"
                samples[rid] = x
                rows.append(_recording(rid, unit, scenario, x, rate, trial=f"{scenario}-{k}"))
    return read_dataset(write_dataset(folder / "two-rates", pd.DataFrame(rows), samples))


def test_a_protocol_without_cells_stands_in_with_its_reason(tmp_path):
    recordings = hundred_hz(tmp_path).recordings
    (cell,) = Run("holweg", "speed-holdout").cells_or_stand_in(recordings)
    assert cell.name == NO_CELL
    assert "none of its 24 slip recordings gives a speed (speed_mm_s is empty)" in cell.skip
    assert "scenarios" not in cell.skip  # the speeds are missing, not a scenario
    no_material = recordings.assign(material=None)
    (cell,) = Run("holweg", "material-holdout").cells_or_stand_in(no_material)
    assert "no recording gives a material" in cell.skip
    assert "no recording slips" in SpeedHoldout().why_no_cells(
        recordings[recordings["scenario"] == "press"]
    )
    assert len(Run("holweg", "window-size").cells_or_stand_in(recordings)) > 1


def test_check_names_every_protocol_and_the_windows_it_uses_once(tmp_path):
    ds = two_rates(tmp_path)
    runs = [
        Run("holweg", WindowSize(windows=["100ms", "200ms", 50])),
        Run("holweg", Streaming(window="200ms", hop="100ms")),
        Run("holweg", SpeedHoldout()),
    ]
    result = check_dataset(ds, runs)
    assert list(result.windows.columns) == WINDOW_COLUMNS
    assert not result.windows.isna().any().any()
    assert not result.windows.duplicated(["sensor_type", "sensor_instance", "window"]).any()
    used = {
        (u, int(w)): (ms, by)
        for u, w, ms, by in result.windows[
            ["sensor_type", "window", "window_ms", "used_by"]
        ].itertuples(index=False)
    }
    assert set(used) == {("A", 10), ("A", 20), ("A", 50), ("B", 25), ("B", 50)}
    assert used["A", 20] == (200.0, "window-size, streaming")
    assert used["B", 50] == (200.0, "window-size, streaming")  # 50 samples and 200 ms: one row
    assert used["A", 50] == (500.0, "window-size")
    speed = result.cells[result.cells["protocol"] == "speed-holdout"]
    assert len(speed) == 1 and speed["verdict"].iloc[0] == "skipped"
    assert "gives a speed" in speed["reason"].iloc[0]
    assert set(result.cells["protocol"]) == {"window-size", "streaming", "speed-holdout"}


def test_check_command_on_data_without_speeds(tmp_path, cli):
    path = hundred_hz(tmp_path).path
    code, out, err = cli(["dataset", "check", str(path), "--protocol", "speed-holdout"])
    assert code == 0, err
    assert "## speed-holdout: no cell" in out and "gives a speed" in out
    header = next(line for line in out.splitlines() if "window_ms" in line)
    assert [c.strip() for c in header.strip("|").split("|")] == WINDOW_COLUMNS


def test_check_counts_classes_at_the_windows_asked_for(tmp_path, cli):
    # issue 54: slip in 4-frame bursts; windows of 5 frames hold slip by majority, windows of
    # 50 (the first table's fixed size before) none: the check said there was no slip at all
    ds = bursty_labels(tmp_path)
    result = check_dataset(ds, [Run("holweg", WindowSize(windows=[5]), labels="majority")])
    assert list(result.units.columns) == UNIT_COLUMNS
    assert set(result.units["window"]) == {5}
    slip = result.units[result.units["class"] == "slip"]
    assert int(slip["windows"].iloc[0]) > 0 and int(slip["trials"].iloc[0]) > 0
    at_50 = check_dataset(ds, [Run("holweg", WindowSize(windows=[50]), labels="majority")])
    assert int(at_50.units.loc[at_50.units["class"] == "slip", "windows"].iloc[0]) == 0
    code, out, err = cli(
        [
            "dataset",
            "check",
            str(ds.path),
            "--protocol",
            "window-size",
            "--protocol-param",
            "windows=[5]",
            "--labels",
            "majority",
        ]
    )
    assert code == 0, err
    assert "windows of 50 samples" not in out
    first = out.split("## ")[1]  # the first table: classes per unit, at window 5
    assert "| IMU           | index             |        5 | slip" in first
