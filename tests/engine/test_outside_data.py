"""Datasets shaped like real labs' run through every protocol with every built-in detector without
a dead end: each cell runs or is skipped with its reason. The same recordings in another row
order give the same results. A one-class dataset is tested with a model trained on another."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from datagen import subset
from rendering import render_report

from slipbench.data.read import read_dataset
from slipbench.data.write import write_dataset
from slipbench.engine.registry import detectors, protocols
from slipbench.engine.runner import Run, evaluate
from slipbench.store.results import ResultsStore

FAST = {
    "lstm": {"max_epochs": 1, "validation_fraction": 0.2},
    "minirocket": {"n_kernels": 168},
    "wavelet-svm": {"n_components": 50},
}


def _recording(rid, unit, scenario, samples, rate, material=None, speed=None, trial=None):
    return dict(
        recording_id=rid,
        sensor_type=unit[0],
        sensor_instance=unit[1],
        scenario=scenario,
        material=material,
        speed_mm_s=speed,
        sampling_rate_hz=rate,
        channels=tuple(f"c{i}" for i in range(samples.shape[1])),
        units=("count",) * samples.shape[1],
        source="test lab",
        trial=trial or rid,
    )


def taxels(folder, seed=0):
    """(a) A 48-taxel array at about 60 Hz: integer counts, trials of 250-400 frames that hold,
    then slip for 20-100 frames, some ending in a drop (unlabelled); per-trial logger rates."""
    rng = np.random.default_rng(seed)
    rows, samples, labels = [], {}, {}
    for k in range(16):
        n, onset, slip = (
            int(rng.integers(250, 401)),
            int(rng.integers(100, 140)),
            int(rng.integers(20, 101)),
        )
        counts = rng.integers(2000, 2100, size=(n, 48))
        counts[onset : onset + slip] += rng.integers(
            -60, 60, size=(slip, 48)
        )  # slip shakes the taxels
        lab = np.zeros(n, np.int8)
        lab[onset : onset + slip] = 1
        if k % 3 == 0:
            lab[onset + slip :] = -1  # dropped
        rid = f"trial-{k:02d}"
        samples[rid], labels[rid] = counts, lab
        rows.append(
            _recording(
                rid,
                ("Taxels", "left"),
                "hold-slip",
                counts,
                float(rng.uniform(59.7, 60.0)),
                material=("foam", "wood")[k % 2],
                speed=25.0,
            )
        )
    return read_dataset(write_dataset(folder / "taxels", pd.DataFrame(rows), samples, labels))


def vibration(folder, classes=("slip",), seed=1, n_trials=10):
    """(b) One vibration channel at 2.2 kHz; by default every trial slides (one class)."""
    rng = np.random.default_rng(seed)
    rows, samples = [], {}
    for k in range(n_trials):
        for scenario in classes:
            x = rng.normal(0, 3.0 if scenario == "slip" else 1.0, (2200, 1)) + 100.0
            rid = f"{scenario}-{k}"
            samples[rid] = x
            rows.append(
                _recording(rid, ("Vib", "probe"), scenario, x, 2200.0, material="steel", speed=10.0)
            )
    return read_dataset(
        write_dataset(folder / f"vib-{'-'.join(classes)}", pd.DataFrame(rows), samples)
    )


def hundred_hz(folder, seed=2):
    """(c) 100 Hz data from two fingers sharing trials: slip and pressing on three objects."""
    rng = np.random.default_rng(seed)
    rows, samples = [], {}
    for k in range(12):
        for scenario in ("slip", "press"):
            for finger in ("th", "ff"):
                x = np.cumsum(rng.normal(0, 2.0 if scenario == "slip" else 1.0, (300, 24)), axis=0)
                rid = f"{scenario}-{k}-{finger}"
                samples[rid] = x
                rows.append(
                    _recording(
                        rid,
                        ("BioTacSP", finger),
                        scenario,
                        x,
                        100.0,
                        material=("cup", "box", "ball")[k % 3],
                        trial=f"{scenario}-{k}",
                    )
                )
    return read_dataset(write_dataset(folder / "hundred", pd.DataFrame(rows), samples))


def _usable() -> list[str]:
    """The built-in detectors whose dependencies are installed (minirocket needs aeon)."""
    return [d for d in detectors.names() if detectors.status(d).state == "ok"]


def _all_runs(split, labels, windows):
    runs = []
    for d in _usable():
        for p in protocols.names():
            protocol = protocols.get(p)()
            if p == "window-size":
                protocol.set_params(windows=windows)
            runs.append(
                Run(detectors.get(d)().set_params(**FAST.get(d, {})), protocol, split, 0, labels)
            )
    return runs


@pytest.mark.slow
@pytest.mark.parametrize(
    "shape, split, labels, windows",
    [
        (taxels, "grouped", "majority", ["100ms", "250ms", "500ms"]),
        (taxels, "paper", "last", [5, 10]),
        (hundred_hz, "grouped", "scenario", ["50ms", "100ms", "250ms"]),
        (vibration, "paper", "scenario", [5, 50]),
    ],
)
def test_every_protocol_and_detector_runs_or_skips_with_a_reason(
    tmp_path, shape, split, labels, windows
):
    rows = evaluate(
        shape(tmp_path),
        _all_runs(split, labels, windows),
        ResultsStore(tmp_path / "out"),
        progress=False,
    )
    assert set(rows["status"]) <= {"ok", "skipped"}, rows.loc[
        ~rows["status"].isin(["ok", "skipped"]), "reason"
    ].tolist()
    assert (rows.loc[rows["status"] == "skipped", "reason"].str.len() > 0).all()
    assert set(rows["protocol"]) == set(protocols.names()) and set(rows["detector"]) == set(
        _usable()
    )
    if shape is not vibration:  # the one-class dataset can train nothing on its own
        assert (rows["status"] == "ok").sum() > 0
    # no dropped class: every model trained on both classes, as balanced and recorded in its row
    ok = rows[rows["status"].eq("ok")]
    for column in ("train_slip_windows", "train_nonslip_windows"):
        assert ok.empty or (ok[column] > 0).all(), column
    for fmt in ("md", "latex", "html"):  # every report format renders these rows
        text = render_report(rows, fmt, intervals=True, paper=True)
        assert all(p in text for p in set(rows["protocol"])), fmt


@pytest.mark.slow
def test_one_class_data_is_tested_with_a_model_trained_elsewhere(tmp_path, cli):
    train, test = vibration(tmp_path, ("slip", "press"), seed=3), vibration(tmp_path, ("slip",))
    code, out, err = cli(
        [
            "evaluate",
            "--detector",
            "holweg",
            "--protocol",
            "window-size",
            "--train-dataset",
            str(train.path),
            "--dataset",
            str(test.path),
            "--out",
            str(tmp_path / "res"),
            "--quiet",
        ]
    )
    assert code == 0, err
    rows = pd.read_parquet(tmp_path / "res" / "results.parquet")
    assert (rows["status"] == "ok").all() and (rows["split"] == "datasets").all()
    assert rows["reason"].str.contains("holds slip windows only: accuracy is the TP rate").all()
    np.testing.assert_allclose(rows["accuracy"], rows["tp_rate"])
    assert rows["tn_rate"].isna().all()
    code, _, err = cli(
        [
            "evaluate",
            "--detector",
            "holweg",
            "--protocol",
            "window-size",
            "--train-dataset",
            str(train.path),
            "--dataset",
            str(hundred_hz(tmp_path).path),
            "--out",
            str(tmp_path / "r2"),
        ]
    )
    assert code == 2 and "--sensor-map" in err


@pytest.mark.slow
def test_a_band_at_0_hz_is_recorded_and_flagged(tmp_path):
    rows = evaluate(
        hundred_hz(tmp_path),
        Run("holweg", "window-size"),
        ResultsStore(tmp_path / "out"),
        progress=False,
    )
    ok = rows[rows["status"] == "ok"]
    bands = ok["fitted"].map(lambda t: json.loads(t)["band_hz"])
    assert len(ok) and all(len(b) == 2 for b in bands)
    starts_at_zero = ok[[b[0] == 0 for b in bands]]
    assert starts_at_zero["warnings"].str.contains("starts at 0 Hz").all()


def _shuffled_copy(src, dst, seed):
    dst.mkdir()
    for name in ("recordings.parquet", "samples.parquet"):
        table = pq.read_table(src / name)
        order = np.random.default_rng(seed).permutation(table.num_rows)
        pq.write_table(table.take(pa.array(order)), dst / name)


@pytest.mark.slow
def test_row_order_of_the_files_leaves_results_identical(tmp_path, small_path):
    units = small_path.parent / "units"
    if not units.exists():
        ds = read_dataset(small_path)
        keep = ds.recordings["sensor_type"].eq("Nano17") & ds.recordings["sensor_instance"].eq(
            "index"
        )
        part = subset(ds, keep)
        write_dataset(units, part.recordings, part.samples, part.slip_labels or None)
    _shuffled_copy(units, tmp_path / "shuffled", seed=7)
    figures = [
        "key",
        "status",
        "accuracy",
        "accuracy_lo",
        "accuracy_hi",
        "tp_rate",
        "tn_rate",
        "auroc",
        "n_test",
        "fitted",
    ]
    out = []
    for i, path in enumerate((units, tmp_path / "shuffled")):
        for split in ("paper", "grouped"):
            evaluate(
                read_dataset(path),
                Run("holweg", "window-size", split),
                ResultsStore(tmp_path / f"r{i}"),
                progress=False,
            )
        out.append(
            pd.read_parquet(tmp_path / f"r{i}" / "results.parquet")[figures]
            .sort_values("key")
            .reset_index(drop=True)
        )
    pd.testing.assert_frame_equal(out[0], out[1])
