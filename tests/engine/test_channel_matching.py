"""The channels input matches channels by name and unit: a unit wired in another order is
reordered (its rows say so), a unit naming other channels or units is not paired by position
(its cells are skipped with both lists), within one dataset and across two."""

from __future__ import annotations

import numpy as np
import pandas as pd
from labshapes import FORCE, holdslip

from slipbench.data.channels import channel_match, channel_orders
from slipbench.data.transfer import combine
from slipbench.engine.plan import Run
from slipbench.engine.runner import _signals, evaluate, make_plan
from slipbench.store.results import ResultsStore

SWAPPED = (("fz", "N"), ("fx", "N"), ("fy", "N"))
# the shared fixture's second finger: a gyro where the first has a force channel
GYRO = (("gz", "rad/s"), ("fx", "N"), ("fy", "N"))


def _runs(input="channels", split="grouped"):
    from slipbench.protocols.cross_instance import CrossInstance

    return [Run("features", CrossInstance(), split, 0, labels="majority", input=input)]


def test_orders_follow_the_first_recording_with_the_same_channels():
    rec = pd.DataFrame(
        {
            "channels": [("a", "b"), ("b", "a"), ("a", "b"), ("a", "c"), ("x", "x")],
            "units": [("N", "N"), ("N", "N"), ("N", "V"), ("N", "N"), ("N", "N")],
        }
    )
    orders = channel_orders(rec)
    assert orders[0] is None and orders[1].tolist() == [1, 0]
    # another unit is another channel; a name given twice cannot be matched by name
    assert orders[2] is None and orders[3] is None and orders[4] is None


def test_a_unit_wired_in_another_order_reads_as_the_others(tmp_path):
    ds = holdslip(tmp_path, {"index": FORCE, "middle": SWAPPED})
    run = _runs()[0]
    signals = _signals(ds, [run])
    plan = make_plan(signals, [(run, run.cells(ds.recordings))], ds.fingerprint, set())
    crossed = [
        pc
        for pc in plan.cells
        if not pc.skip and pc.cell.train.sensors != pc.cell.test.sensors and pc.test is not None
    ]
    assert crossed, [pc.skip for pc in plan.cells]
    for pc in crossed:
        assert pc.notes == [
            "channels matched by name and unit: Nano17 middle reordered from "
            "[fz (N), fx (N), fy (N)] to [fx (N), fy (N), fz (N)]"
        ]
        # every column of the windows holds one name: the middle's fx is read as column 0
        test = plan.data_of(pc).values(pc.windows("test"), pc.cell, "channels")
        rec = ds.recordings
        for i in np.flatnonzero(rec["sensor_instance"].to_numpy()[test.recording] == "middle")[:3]:
            r, start = test.recording[i], test.index[i] * pc.cell.window
            raw = ds.samples[rec["recording_id"][r]][1 + start : 1 + start + pc.cell.window]
            np.testing.assert_array_equal(test.x[i], raw[:, [1, 2, 0]].astype(np.float32))
    same = [pc for pc in plan.cells if pc.cell.train.sensors == pc.cell.test.sensors]
    assert all(not pc.notes for pc in same if len(pc.cell.train.sensors) == 1)


def test_reordered_cells_run_and_their_rows_say_so(tmp_path):
    ds = holdslip(tmp_path, {"index": FORCE, "middle": SWAPPED}, trials=4, n=300)
    rows = evaluate(ds, _runs(), ResultsStore(tmp_path / "o"), progress=False)
    ok = rows[rows["status"] == "ok"]
    crossed = ok[ok["train_instance"] != ok["test_instance"]]
    assert len(crossed) and crossed["warnings"].str.contains("Nano17 middle reordered").all()
    alone = ok[(ok["train_instance"] == ok["test_instance"]) & (ok["train_instance"] != "combined")]
    assert not alone["warnings"].str.contains("reordered").any()


def test_other_channels_or_units_are_never_paired_by_position(tmp_path):
    ds = holdslip(tmp_path, {"index": FORCE, "middle": GYRO}, trials=4, n=300)
    rows = evaluate(ds, _runs(), ResultsStore(tmp_path / "o"), progress=False)
    crossed = rows[rows["train_instance"] != rows["test_instance"]]
    assert len(crossed) and (crossed["status"] == "skipped").all()
    index, middle = (
        "Nano17 index has [fx (N), fy (N), fz (N)]",
        "Nano17 middle has [gz (rad/s), fx (N), fy (N)]",
    )
    said = "the channels input matches channels by name and unit, and this cell's recordings name different ones: "
    for _, row in crossed.iterrows():  # the training unit's channels first
        first, then = (middle, index) if row["train_instance"] == "middle" else (index, middle)
        assert row["reason"] == f"{said}{first}; {then}"
    # each unit tested on itself still runs; the univariate input is not concerned
    assert (rows[rows["train_instance"] == "index"]["status"] == "ok").any()


def test_across_datasets_channels_are_matched_by_name_and_unit(tmp_path):
    a = holdslip(tmp_path / "a", {"index": FORCE}, trials=3, n=300)
    b = holdslip(tmp_path / "b", {"index": SWAPPED}, trials=3, n=300, seed=8)
    c = holdslip(tmp_path / "c", {"index": (("fx", "N"), ("fy", "N"), ("fz", "kN"))}, 3, 300)
    both = combine(a, b)
    rec = both.recordings
    reason, note = channel_match(rec, np.arange(len(rec)))
    assert reason == "" and note == (
        "channels matched by name and unit: test dataset's Nano17 index reordered from "
        "[fz (N), fx (N), fy (N)] to [fx (N), fy (N), fz (N)]"
    )
    rec = combine(a, c).recordings
    reason, note = channel_match(rec, np.arange(len(rec)))
    assert note == "" and reason.endswith(
        "training dataset's Nano17 index has [fx (N), fy (N), fz (N)]; test dataset's Nano17 "
        "index has [fx (N), fy (N), fz (kN)]"
    )
