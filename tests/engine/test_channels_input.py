"""The channels input end to end: a detector that reads the raw channels sees what the
univariate reduction throws away, on the same cells; cells that cannot form one window array
are skipped saying why; the input is part of keys and rows; what cannot run is refused first."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from slipbench.data.read import read_dataset
from slipbench.data.signals import channel_scales, standardized
from slipbench.data.write import write_dataset
from slipbench.engine.plan import Run, keys
from slipbench.engine.runner import _payload, _signals, evaluate, make_plan
from slipbench.errors import UsageError
from slipbench.store.results import ResultsStore

FAST_SVM = {"n_components": 50}


def turning(folder, counts=(("BioTacSP", "ff", 2), ("BioTacSP", "th", 2)), seed=0):
    """Units whose slip turns the contact force without changing its size: two channels
    a_t = r (cos th_t, sin th_t), the angle wandering while slipping and still while
    pressing; ||a_t|| is the same in both, so s holds noise alone. Integer counts, 200 Hz,
    trials shared by the units. ``counts``: (type, instance, channels); extra channels hold
    noise."""
    rng = np.random.default_rng(seed)
    rows, samples = [], {}
    for k in range(12):
        for scenario in ("slip", "press"):
            for sensor, finger, n_ch in counts:
                n = 600
                step = rng.normal(0, 0.3 if scenario == "slip" else 0.0, n)
                angle = rng.uniform(0, 2 * np.pi) + np.cumsum(step)
                a = 500 * np.stack([np.cos(angle), np.sin(angle)], axis=1)
                a = np.hstack([a, np.zeros((n, n_ch - 2))]) + rng.normal(0, 1.0, (n, n_ch))
                rid = f"{scenario}-{k}-{finger}"
                samples[rid] = np.round(a).astype(np.int64)
                rows.append(
                    dict(
                        recording_id=rid,
                        sensor_type=sensor,
                        sensor_instance=finger,
                        scenario=scenario,
                        material=("cup", "box")[k % 2],
                        speed_mm_s=None,
                        sampling_rate_hz=200.0,
                        channels=tuple(f"e{i}" for i in range(n_ch)),
                        units=("count",) * n_ch,
                        source="test lab",
                        trial=f"{scenario}-{k}",
                    )
                )
    return read_dataset(write_dataset(folder / "turning", pd.DataFrame(rows), samples))


def _runs(protocol, kinds=("univariate", "channels"), split="grouped"):
    from slipbench.engine.registry import detectors

    return [
        Run(detectors.get("wavelet-svm")().set_params(**FAST_SVM), protocol, split, 0, input=kind)
        for kind in kinds
    ]


@pytest.mark.slow
def test_channels_see_what_the_reduction_throws_away(tmp_path):
    from slipbench.protocols.window_size import WindowSize

    rows = evaluate(
        turning(tmp_path),
        _runs(WindowSize(windows=[50])),
        ResultsStore(tmp_path / "out"),
        progress=False,
    )
    assert set(rows["status"]) == {"ok"}, rows["reason"].tolist()
    by = rows.groupby("input")["accuracy"]
    assert by.min()["channels"] > 0.9  # the turning force, seen
    assert by.max()["univariate"] < 0.75  # ||a|| does not turn
    # the same cells and windows on both sides, told apart by key and row
    uni, ch = (rows[rows["input"] == k].set_index(["cell"]) for k in ("univariate", "channels"))
    assert (uni["test_slip_windows"] == ch.loc[uni.index, "test_slip_windows"]).all()
    assert not set(uni["key"]) & set(ch["key"])


def test_univariate_keys_stay_those_of_earlier_versions(tmp_path, monkeypatch):
    """The univariate input adds nothing to what keys hash (results cached before the input
    existed stay valid); channels add {"input": "channels"} to the model's and the cell's."""
    from slipbench.engine import plan as plan_module
    from slipbench.protocols.window_size import WindowSize

    ds = turning(tmp_path)
    protocol = WindowSize(windows=[50])
    cell = next(iter(protocol.cells(ds.recordings)))
    hashed: list[dict] = []
    monkeypatch.setattr(plan_module, "cell_key", lambda payload: hashed.append(payload) or "k")
    keys(Run("wavelet-svm", protocol, "grouped", 0), cell, ds.fingerprint)
    assert hashed and all("input" not in payload for payload in hashed)
    hashed.clear()
    keys(Run("wavelet-svm", protocol, "grouped", 0, input="channels"), cell, ds.fingerprint)
    assert len(hashed) == 2 and all(payload["input"] == "channels" for payload in hashed)


def test_channels_are_standardized_by_the_training_windows(tmp_path):
    from slipbench.protocols.window_size import WindowSize

    ds = turning(tmp_path)
    (run,) = _runs(WindowSize(windows=[50]), ("channels",))
    signals = _signals(ds, [run])
    plan = make_plan(signals, [(run, run.cells(ds.recordings))], ds.fingerprint, set())
    task = plan.tasks[0]
    job = _payload(plan, task, ResultsStore(tmp_path / "out"), False, None)
    data = plan.data_of(task.first)
    raw_train = data.values(task.first.windows("train"), task.first.cell, "channels").x
    raw_test = data.values(task.first.windows("test"), task.first.cell, "channels").x
    scales = channel_scales(raw_train)
    np.testing.assert_array_equal(job.train_x, standardized(raw_train, scales))
    np.testing.assert_array_equal(job.tests[0].x, standardized(raw_test, scales))
    assert job.train_x.shape[2] == 2 and abs(float(np.median(job.train_x))) < 0.5


@pytest.mark.slow
def test_a_cell_pooling_channel_counts_is_skipped_saying_so(tmp_path):
    from slipbench.protocols.cross_instance import CrossInstance

    ds = turning(tmp_path, (("BioTacSP", "ff", 3), ("BioTacSP", "th", 2)))
    rows = evaluate(
        ds, _runs(CrossInstance(), ("channels",)), ResultsStore(tmp_path / "o"), progress=False
    )
    skipped = rows[rows["status"] == "skipped"]
    assert len(skipped) and skipped["reason"].str.contains("matches channels by name").all()
    for layout in (
        "ff has [e0 (count), e1 (count), e2 (count)]",
        "th has [e0 (count), e1 (count)]",
    ):
        assert skipped["reason"].str.contains(layout, regex=False).all()
    ok = rows[rows["status"] == "ok"]  # a unit tested on itself has one count
    assert len(ok) and (ok["train_instance"] == ok["test_instance"]).all()


def test_what_cannot_run_is_refused_before_any_work():
    with pytest.raises(UsageError, match="reads the univariate input, not channels"):
        Run("holweg", "window-size", input="channels").validate()
    with pytest.raises(UsageError, match="--normalize unit scales the univariate signal"):
        Run("wavelet-svm", "window-size", normalize="unit", input="channels")
    with pytest.raises(UsageError, match="unknown input"):
        Run("wavelet-svm", "window-size", input="taxels")


@pytest.mark.slow
def test_evaluate_both_runs_each_input_a_detector_reads(tmp_path, cli):
    path = turning(tmp_path).path
    code, out, err = cli(
        [
            "evaluate", "--detector", "holweg,wavelet-svm", "--protocol", "window-size",
            "--protocol-param", "windows=[50]", "--dataset", str(path), "--split", "grouped",
            "--param", "n_components=50", "--input", "both", "--out", str(tmp_path / "r"), "--quiet",
        ]
    )  # fmt: skip
    assert code == 0, err
    assert (
        "detector 'holweg' reads the univariate input only: no run with the channels input" in err
    )
    assert "## wavelet-svm (channels) x window-size" in out and "## holweg x window-size" in out
    rows = pd.read_parquet(tmp_path / "r" / "results.parquet")
    assert sorted(map(tuple, rows[["detector", "input"]].drop_duplicates().to_numpy())) == [
        ("holweg", "univariate"),
        ("wavelet-svm", "channels"),
        ("wavelet-svm", "univariate"),
    ]
    code, _, err = cli(
        ["evaluate", "--detector", "holweg", "--protocol", "window-size", "--dataset", str(path),
         "--input", "channels", "--out", str(tmp_path / "r2")]
    )  # fmt: skip
    assert code == 2 and "no detector chosen reads the channels input" in err


@pytest.mark.slow
def test_streams_of_channels_time_the_turning_onsets(tmp_path):
    """Streaming reads the standardized channels too: contact held still, then turning, with
    per-sample labels; the channels detector finds the onsets the reduction hides."""
    from slipbench.engine.registry import detectors
    from slipbench.protocols.streaming import Streaming

    rng = np.random.default_rng(4)
    rows, samples, labels = [], {}, {}
    for k in range(16):
        for scenario in ("hold-slip", "press"):
            n, onset = 800, int(rng.integers(300, 500))
            step = rng.normal(0, 0.3, n) * ((np.arange(n) >= onset) & (scenario == "hold-slip"))
            angle = rng.uniform(0, 2 * np.pi) + np.cumsum(step)
            rid = f"{scenario}-{k}"
            samples[rid] = 500 * np.stack([np.cos(angle), np.sin(angle)], 1) + rng.normal(
                0, 1, (n, 2)
            )
            labels[rid] = (step != 0).astype(np.int8)
            rows.append(
                dict(recording_id=rid, sensor_type="S", sensor_instance="u", scenario=scenario,
                     material="cup", speed_mm_s=None, sampling_rate_hz=200.0, channels=("x", "y"),
                     units=("N", "N"), source="test lab", trial=rid)
            )  # fmt: skip
    ds = read_dataset(write_dataset(tmp_path / "onsets", pd.DataFrame(rows), samples, labels))
    runs = [
        Run(detectors.get("wavelet-svm")().set_params(**FAST_SVM), Streaming(window=40, hop=10), "grouped", 0, "majority", input=kind)
        for kind in ("univariate", "channels")
    ]  # fmt: skip
    out = evaluate(ds, runs, ResultsStore(tmp_path / "out"), progress=False).set_index("input")
    assert (out["status"] == "ok").all(), out["reason"].tolist()
    assert out.loc["channels", "detection_rate"] > 0.9
    assert out.loc["channels", "median_delay_ms"] < 400
    # the reduction's detector alarms all the time (here about 320 a minute); the channels' never
    assert (
        out.loc["channels", "false_alarms_per_min"]
        < 1
        < 30
        < out.loc["univariate", "false_alarms_per_min"]
    )
