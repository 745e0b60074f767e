"""Univariate reduction, windowing, downsampling, balancing and both splits."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from slipbench.data.signals import Signals, balance, split, univariate


def test_univariate_is_the_lag_one_difference_of_the_norm():
    a = np.array([[3.0, 4.0], [6.0, 8.0], [0.0, 1.0]])
    np.testing.assert_allclose(univariate(a), [5.0, -9.0])
    assert univariate(a).dtype == np.float32


def test_univariate_keeps_small_changes_on_a_large_load():
    a = np.array([[1e4, 0, 0], [1e4 + 1e-3, 0, 0]], dtype=np.float32)
    assert univariate(a)[0] == pytest.approx(float(a[1, 0]) - float(a[0, 0]), rel=1e-6)


def _signals(lengths, labels=None, scenario="slip"):
    rec = pd.DataFrame(
        {"recording_id": [f"r{i}" for i in range(len(lengths))], "scenario": scenario}
    )
    parts = [np.arange(n, dtype=np.float32) + 1000 * i for i, n in enumerate(lengths)]
    labels = np.ones(sum(lengths), np.int8) if labels is None else np.asarray(labels, np.int8)
    return Signals(np.concatenate(parts), np.r_[0, np.cumsum(lengths)], rec, labels)


def test_windows_never_cross_recordings_and_drop_tails():
    w = _signals([7, 3, 10]).windows(3)
    assert w.x.shape == (2 + 1 + 3, 3)
    np.testing.assert_array_equal(w.recording, [0, 0, 1, 2, 2, 2])
    np.testing.assert_array_equal(w.index, [0, 1, 0, 0, 1, 2])
    np.testing.assert_array_equal(w.x[1], [3, 4, 5])
    np.testing.assert_array_equal(w.x[2], [1000, 1001, 1002])
    np.testing.assert_array_equal(w.x[5], [2006, 2007, 2008])


def test_windows_of_selected_recordings_and_downsampling():
    sig = _signals([8, 8])
    w = sig.windows(4, rows=np.array([1]))
    np.testing.assert_array_equal(w.recording, [1, 1])
    np.testing.assert_array_equal(w.downsample(2).x, [[1000, 1002], [1004, 1006]])


def test_balancing_gives_the_papers_proportions(small):
    w = Signals.from_dataset(small).windows(
        50,
        np.flatnonzero(
            small.recordings["sensor_instance"].eq("index")
            & small.recordings["sensor_type"].eq("Nano17")
        ),
    )
    kept = w.take(balance(w, np.random.default_rng(0)))
    scenario = kept.column("scenario")
    n = len(kept)
    assert (scenario == "slip").sum() == n // 2
    assert (scenario == "press").sum() == (scenario == "free-space").sum() == n // 4
    slip = kept.take(np.flatnonzero(scenario == "slip"))
    per_cell = pd.Series(
        list(zip(slip.column("material"), slip.column("speed_mm_s")))
    ).value_counts()
    assert len(per_cell) == 20 and per_cell.nunique() == 1
    press = kept.take(np.flatnonzero(scenario == "press"))
    assert pd.Series(press.column("material")).value_counts().nunique() == 1
    free = kept.take(np.flatnonzero(scenario == "free-space"))
    counts = pd.Series(free.column("speed_mm_s")).value_counts()
    assert len(counts) == 3 and counts.nunique() == 1


def test_balancing_is_seeded(small):
    w = Signals.from_dataset(small).windows(25)
    a = balance(w, np.random.default_rng(3))
    np.testing.assert_array_equal(a, balance(w, np.random.default_rng(3)))
    assert not np.array_equal(a, balance(w, np.random.default_rng(4)))


@pytest.mark.parametrize("how", ["paper", "grouped"])
def test_splits_halve_and_keep_both_classes(small, how):
    sig = Signals.from_dataset(small)
    rows = np.flatnonzero(
        small.recordings["sensor_type"].eq("OptoForce20")
        & small.recordings["sensor_instance"].eq("middle")
    )
    w = sig.windows(50, rows)
    w = w.take(balance(w, np.random.default_rng(0)))
    train, test = split(w, how, seed=0)
    assert len(np.intersect1d(train, test)) == 0 and len(train) + len(test) == len(w)
    assert abs(len(train) - len(test)) <= 0.1 * len(w)
    for side in (train, test):
        assert set(w.y[side]) == {0, 1}
    shared = np.intersect1d(w.recording[train], w.recording[test])
    if how == "grouped":
        assert len(shared) == 0
    else:
        assert len(shared) > 0  # the paper's split shuffles windows: recordings straddle it


def test_windowing_is_vectorized_enough():
    """8 million samples cut into windows: a smoke check of the vectorized path (the timing is
    reported by the benchmark, not asserted here)."""
    sig = _signals([4000] * 2000)
    w = sig.windows(50)
    assert w.x.shape == (2000 * 80, 50)
    np.testing.assert_array_equal(w.x[80], np.arange(1000, 1050, dtype=np.float32))


def test_windows_take_their_class_from_the_samples_as_asked():
    # one hold-slip recording: held for 6 samples, slipping for 5, then dropped (unlabelled)
    labels = [0] * 6 + [1] * 5 + [-1] * 4
    sig = _signals([15], labels, scenario="hold-slip")
    assert len(sig.windows(4, labelling="scenario")) == 0  # two states: no scenario label
    by = {how: sig.windows(4, labelling=how) for how in ("majority", "any", "last")}
    # windows [0:4] all held, [4:8] 2 held + 2 slip, [8:12] 3 slip + 1 unlabelled (left out)
    for how, expected in (("majority", [0, 1]), ("any", [0, 1]), ("last", [0, 1])):
        np.testing.assert_array_equal(by[how].y, expected, err_msg=how)
        np.testing.assert_array_equal(by[how].index, [0, 1])
    sig = _signals([9], [0, 0, 0, 1, 0, 0, 0, 0, 0], scenario="hold-slip")
    assert sig.windows(3, labelling="majority").y.tolist() == [0, 0, 0]
    assert sig.windows(3, labelling="any").y.tolist() == [0, 1, 0]
    assert sig.windows(3, labelling="last").y.tolist() == [
        0,
        0,
        0,
    ]  # the slip sample is not the last


def test_grouped_split_keeps_each_trial_on_one_side_for_every_unit(small):
    from slipbench.data.signals import trial_sides

    rec = small.recordings
    sides = trial_sides(rec, seed=5)
    per_trial = pd.Series(sides).groupby(rec["trial"].to_numpy()).nunique()
    assert (per_trial == 1).all()  # every recording of a trial, whatever its unit, on one side
    assert 0.4 < sides.mean() < 0.6
    sig = Signals.from_dataset(small)
    test_trials = {}
    for unit in (("Nano17", "index"), ("Nano17", "middle")):
        rows = np.flatnonzero(rec["sensor_type"].eq(unit[0]) & rec["sensor_instance"].eq(unit[1]))
        w = sig.windows(50, rows)
        w = w.take(balance(w, np.random.default_rng(0)))
        train, test = split(w, "grouped", seed=5)
        trials = rec["trial"].to_numpy()
        test_trials[unit] = set(trials[w.recording[test]])
        assert not set(trials[w.recording[train]]) & test_trials[unit]
    train_index = set(
        rec["trial"].to_numpy()[
            np.flatnonzero(rec["sensor_instance"].eq("index").to_numpy() & (sides == 0))
        ]
    )
    assert (
        not test_trials[("Nano17", "middle")] & train_index
    )  # no middle test trial trained the index model


def test_the_paper_split_survives_single_window_strata():
    sig = _signals([8] * 6)
    sig.recordings["scenario"] = ["slip", "slip", "slip", "press", "press", "free-space"]
    sig.recordings["material"] = ["PVC", "PVC", "PVC", "PVC", "PVC", None]
    sig.recordings["speed_mm_s"] = [25.0, 25.0, 25.0, np.nan, np.nan, 50.0]
    sig.labels = np.repeat(np.array([1, 1, 1, 0, 0, 0], np.int8), 8)
    w = sig.windows(4)
    w = w.take(np.r_[0:6, 6:10, 10])  # free-space keeps one window: a stratum of one
    train, test = split(w, "paper", seed=0)
    assert set(w.y[train]) == set(w.y[test]) == {0, 1}
