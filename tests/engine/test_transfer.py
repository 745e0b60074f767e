"""Training on one dataset and testing on another: sensor maps (a type alone included), holdout
pairs that would be one model, rows and reports that name both datasets, normalization of the
signal's scale, and the constant "slip" detector beside a one-class test set."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from datagen import subset

from slipbench.data.format import Dataset
from slipbench.data.read import read_dataset
from slipbench.data.signals import Signals, robust_scale
from slipbench.data.transfer import combine, parse_sensor_map, resolve_sensor_map
from slipbench.data.write import write_dataset
from slipbench.engine.plan import CellData, Run, make_plan
from slipbench.engine.runner import _signals, _stream_test, evaluate
from slipbench.errors import UsageError
from slipbench.protocols.material_holdout import MaterialHoldout
from slipbench.protocols.speed_holdout import SpeedHoldout
from slipbench.protocols.streaming import Streaming
from slipbench.protocols.window_size import WindowSize
from slipbench.report.document import protocol_table
from slipbench.report.provenance import header_tables
from slipbench.store.results import ResultsStore


def lab(
    folder,
    name,
    unit,
    scale,
    materials=("wood",),
    speeds=(20.0,),
    classes=("slip", "press"),
    n=3,
    labelled=False,
    seed=0,
):
    """A tiny dataset of one unit at 1 kHz, 3 channels resting at 100 x ``scale``: slip shakes
    them three times as much as pressing (noise of sd ``scale``), trials of 500 samples. With
    ``labelled``, per-sample labels, slip recordings holding still for their first 150."""
    rng = np.random.default_rng(seed)
    rows, samples, labels = [], {}, {}
    for material in materials:
        for speed in speeds:
            for scenario in classes:
                for k in range(n):
                    sd = np.full(500, 3.0 if scenario == "slip" else 1.0)
                    lab_ = np.full(500, 1 if scenario == "slip" else 0, np.int8)
                    if labelled and scenario == "slip":
                        sd[:150], lab_[:150] = 1.0, 0
                    x = 100.0 * scale + scale * sd[:, None] * rng.normal(size=(500, 3))
                    rid = f"{scenario}-{material}-{speed:g}-{k}"
                    samples[rid], labels[rid] = x, lab_
                    rows.append(
                        dict(
                            recording_id=rid,
                            sensor_type=unit[0],
                            sensor_instance=unit[1],
                            scenario=scenario,
                            material=material,
                            speed_mm_s=speed if scenario == "slip" else None,
                            sampling_rate_hz=1000.0,
                            channels=("e1", "e2", "e3"),
                            units=("count",) * 3,
                            source=f"{name} lab",
                        )
                    )
    return read_dataset(
        write_dataset(folder / name, pd.DataFrame(rows), samples, labels if labelled else None)
    )


def _run(protocol, ds, tmp_path, normalize="none", out="out"):
    return evaluate(
        ds,
        Run("holweg", protocol, "datasets", 0, normalize=normalize),
        ResultsStore(tmp_path / out),
        progress=False,
    )


# ----------------------------------------------------------------------------- sensor maps


def test_a_type_alone_maps_each_instance_by_name_else_to_the_only_one():
    train = [("BioTacSP", "index"), ("BioTacSP", "middle"), ("Nano17", "index")]
    test = [("BioTac", "index"), ("Vib", "probe"), ("Taxels", "left")]
    resolved = resolve_sensor_map(parse_sensor_map(["BioTac=BioTacSP", "Vib=Nano17"]), test, train)
    assert resolved == {
        ("BioTac", "index"): ("BioTacSP", "index"),  # the same-named instance
        ("Vib", "probe"): ("Nano17", "index"),  # the type's only instance
    }
    # an entry naming the instance wins over the type's
    both = parse_sensor_map(["BioTac=BioTacSP", "BioTac:index=BioTacSP:middle"])
    assert resolve_sensor_map(both, test, train)[("BioTac", "index")] == ("BioTacSP", "middle")


@pytest.mark.parametrize(
    "item, message",
    [
        (
            "Vib=BioTacSP",
            "the test unit Vib:probe has no same-named BioTacSP instance in the training dataset, "
            "which has several (BioTacSP:index, BioTacSP:middle); name the one to test it as, "
            "e.g. --sensor-map Vib:probe=BioTacSP:index",
        ),
        ("Vib=OptoForce20", "the training dataset has no sensor OptoForce20 (its units:"),
        ("BioTac:ring=BioTacSP", "the test dataset has no sensor BioTac:ring (its units:"),
        ("BioTac:=BioTacSP", "expected TEST_TYPE[:INSTANCE]=TRAIN_TYPE[:INSTANCE]"),
    ],
)
def test_a_map_that_cannot_be_followed_says_which_entry_and_why(item, message):
    train = [("BioTacSP", "index"), ("BioTacSP", "middle")]
    with pytest.raises(UsageError, match="--sensor-map") as err:
        resolve_sensor_map(parse_sensor_map([item]), [("BioTac", "index"), ("Vib", "probe")], train)
    assert message in str(err.value)


@pytest.mark.slow
def test_cli_type_only_map_runs_and_rows_and_report_name_both_datasets(tmp_path, cli):
    a = lab(tmp_path, "big", ("BioTacSP", "index"), 1000.0)
    b = lab(tmp_path, "small", ("BioTac", "ff"), 1.0, seed=1)
    argv = ["evaluate", "--detector", "holweg", "--protocol", "window-size", "--quiet"]
    argv += ["--protocol-param", "windows=[50]", "--train-dataset", str(a.path)]
    argv += ["--dataset", str(b.path), "--out", str(tmp_path / "res")]
    code, _, err = cli(argv)
    assert code == 2 and "has the name of a unit of the training dataset" in err
    assert "a type alone maps every instance of it" in err
    code, _, err = cli([*argv, "--sensor-map", "BioTac=BioTacSP"])
    assert code == 0, err
    rows = pd.read_parquet(tmp_path / "res" / "results.parquet")
    assert (rows["status"] == "ok").all()
    assert set(rows["train_dataset_path"]) == {str(a.path)}
    assert set(rows["test_dataset_path"]) == {str(b.path)}
    assert set(rows["train_dataset_fingerprint"]) == {a.fingerprint}
    assert set(rows["test_dataset_fingerprint"]) == {b.fingerprint}
    assert json.loads(rows["sensor_map"].iloc[0]) == {"BioTac:ff": "BioTacSP:index"}
    assert (rows["normalize"] == "none").all()
    text = "\n".join(
        f"{line[0]}: {cell[0]}"
        for line, cell in zip(header_tables(rows)[0].rows, header_tables(rows)[0].cells)
    )
    assert "in memory" not in text
    assert (
        f"Trained on: recorded: source big lab (at {a.path}); fingerprint {a.fingerprint}" in text
    )
    assert (
        f"Tested on: recorded: source small lab (at {b.path}); fingerprint {b.fingerprint}" in text
    )
    assert "Sensor map (test unit → training unit): BioTac:ff → BioTacSP:index" in text
    assert "Normalization: none" in text


# ----------------------------------------------------------------------------- holdouts


@pytest.mark.slow
@pytest.mark.parametrize(
    "protocol, column",
    [(MaterialHoldout(), "material"), (SpeedHoldout(), "speed_mm_s")],
)
def test_holdout_across_datasets_skips_pairs_that_are_one_model(tmp_path, protocol, column):
    a = lab(tmp_path, "a", ("BioTacSP", "ff"), 1.0, ("foam", "wood"), (10.0, 20.0))
    b = lab(tmp_path, "b", ("BioTacSP", "ff"), 1.0, ("wood", "steel"), (20.0, 30.0), seed=1)
    rows = _run(protocol, combine(a, b), tmp_path)
    shared, test_only, train_only = (
        ("wood", "steel", "foam") if column == "material" else (20.0, 30.0, 10.0)
    )
    # a value only the training dataset has is no column
    assert set(rows[column]) == {shared, test_only}
    assert train_only not in set(rows[column])
    one = rows[rows[column] == test_only]
    assert set(one["training"]) == {"with", "without"} and (one["status"] == "skipped").all()
    assert one["reason"].str.startswith("with and without are the same model").all()
    assert one["reason"].str.contains(f"holds no {column}").all()
    both = rows[rows[column] == shared]
    assert (both["status"] == "ok").all(), both["reason"].tolist()
    # "with" trains on the shared value, "without" does not: two models
    assert both["model_key"].nunique() == 2


@pytest.mark.slow
def test_holdout_within_one_dataset_runs_every_pair(tmp_path):
    a = lab(tmp_path, "a", ("BioTacSP", "ff"), 1.0, ("foam", "wood"), (10.0,), n=4)
    rows = evaluate(
        a,
        Run("holweg", MaterialHoldout(), "paper", 0),
        ResultsStore(tmp_path / "o"),
        progress=False,
    )
    assert len(rows) == 4 and (rows["status"] == "ok").all()


# ----------------------------------------------------------------------------- normalization


def test_robust_scale_is_median_and_mad_with_fallbacks():
    rng = np.random.default_rng(0)
    centre, scale = robust_scale(5.0 + 2.0 * rng.normal(size=200_000))
    assert centre == pytest.approx(5.0, abs=0.02) and scale == pytest.approx(2.0, rel=0.02)
    # a burst in a tenth of the signal hardly moves it
    x = rng.normal(size=10_000)
    x[:1000] *= 50
    assert robust_scale(x)[1] < 1.3
    # integer counts mostly at rest: the MAD is 0, the mean absolute deviation stands in
    counts = np.zeros(100)
    counts[:10] = 4.0
    assert robust_scale(counts) == (0.0, pytest.approx(1.2533 * 0.4))
    assert robust_scale(np.full(7, 3.0)) == (3.0, 1.0)


def test_unit_statistics_come_from_the_training_side(tmp_path):
    a = lab(tmp_path, "a", ("BioTacSP", "ff"), 1000.0)
    b = lab(tmp_path, "b", ("BioTacSP", "ff"), 1.0, seed=1)
    signals = Signals.from_dataset(combine(a, b))
    data = CellData(signals, "datasets", 0, normalize="unit")
    side = signals.recordings["dataset_side"].to_numpy()
    train_scale, test_scale = data.scales[side == "train", 1], data.scales[side == "test", 1]
    assert len(set(train_scale)) == 1 and len(set(test_scale)) == 1  # one per unit and dataset
    assert train_scale[0] / test_scale[0] == pytest.approx(1000.0, rel=0.2)
    o = signals.offsets
    for which in (side == "train", side == "test"):
        s = np.concatenate([data.signals.buffer[o[r] : o[r + 1]] for r in np.flatnonzero(which)])
        assert robust_scale(s) == (pytest.approx(0.0, abs=1e-3), pytest.approx(1.0, rel=1e-3))
    # within one dataset, split by trials: only the training trials give the statistics
    grouped = CellData(Signals.from_dataset(a), "grouped", 0, normalize="unit")
    s = Signals.from_dataset(a)
    train_rows = np.flatnonzero(grouped._sides == 0)
    expected = robust_scale(
        np.concatenate([s.buffer[s.offsets[r] : s.offsets[r + 1]] for r in train_rows])
    )
    assert tuple(grouped.scales[0]) == pytest.approx(expected)
    # none leaves the signal itself
    assert CellData(signals, "datasets", 0).signals is signals


@pytest.mark.slow
def test_normalizing_by_unit_lets_a_threshold_cross_scales(tmp_path):
    a = lab(tmp_path, "big", ("BioTacSP", "ff"), 1000.0, n=4)
    b = lab(tmp_path, "small", ("BioTacSP", "ff"), 1.0, n=4, seed=1)
    ds = combine(a, b)
    protocol = WindowSize(windows=[50])
    raw = _run(protocol, ds, tmp_path)
    unit = _run(protocol, ds, tmp_path, "unit")
    per_recording = _run(protocol, ds, tmp_path, "recording")
    assert (raw["status"] == "ok").all() and (unit["status"] == "ok").all()
    assert (per_recording["status"] == "ok").all()
    assert list(unit["normalize"]) == ["unit"] and list(raw["normalize"]) == ["none"]
    assert unit["key"].iloc[0] != raw["key"].iloc[0] != per_recording["key"].iloc[0]
    assert "normalize_scale_train" not in raw
    ratio = unit["normalize_scale_train"].iloc[0] / unit["normalize_scale_test"].iloc[0]
    assert ratio == pytest.approx(1000.0, rel=0.2)
    # the threshold learnt at scale 1000 calls nothing slip at scale 1; normalized, it transfers
    assert raw["tp_rate"].iloc[0] < 0.1 and raw["accuracy"].iloc[0] < 0.6
    assert unit["accuracy"].iloc[0] > 0.9


@pytest.mark.slow
def test_streaming_cells_stream_the_normalized_signal(tmp_path):
    a = lab(tmp_path, "big", ("BioTacSP", "ff"), 1000.0, labelled=True)
    b = lab(tmp_path, "small", ("BioTacSP", "ff"), 1.0, labelled=True, seed=1)
    ds = combine(a, b)
    run = Run("holweg", Streaming(window=50, hop=25), "datasets", 0, normalize="unit")
    signals = _signals(ds, [run])
    plan = make_plan(signals, [(run, run.cells(ds.recordings))], ds.fingerprint, set())
    (pc,) = [p for p in plan.cells if not p.skip]
    streamed = np.concatenate(_stream_test(plan.data_of(pc).signals, pc).test.signals)
    assert robust_scale(streamed)[1] == pytest.approx(1.0, rel=1e-3)
    rows = _run(Streaming(window=50, hop=25), ds, tmp_path, "unit")
    assert (rows["status"] == "ok").all() and rows["detection_rate"].iloc[0] > 0.5


def test_unknown_normalization_is_refused(tmp_path, cli):
    code, _, err = cli(
        ["evaluate", "--detector", "holweg", "--protocol", "window-size", "--normalize", "z"]
    )
    assert code == 2 and "--normalize" in err
    with pytest.raises(UsageError, match="unknown normalization 'z'"):
        Run("holweg", "window-size", normalize="z")


# ----------------------------------------------------------------------------- one class


@pytest.mark.slow
def test_a_one_class_test_set_shows_what_a_constant_slip_detector_scores(tmp_path):
    a = lab(tmp_path, "a", ("BioTacSP", "ff"), 1.0)
    b = lab(tmp_path, "b", ("BioTacSP", "ff"), 1.0, classes=("slip",), seed=1)
    rows = _run(WindowSize(windows=[50]), combine(a, b), tmp_path)
    assert (rows["status"] == "ok").all()
    assert (rows["constant_slip_accuracy"] == 1.0).all()
    table = protocol_table(rows)
    assert (
        '1 of 1 finished cells test on one class only: there a constant "slip" detector scores 100 %'
        in table
    )
    # a test set of both classes has no such column
    both = _run(
        WindowSize(windows=[50]),
        combine(a, lab(tmp_path, "c", ("BioTacSP", "ff"), 1.0)),
        tmp_path,
        out="o2",
    )
    assert "constant_slip_accuracy" not in both and "constant" not in protocol_table(both)


# ----------------------------------------------------------------------------- real recordings

DOS = Path(__file__).resolve().parents[3] / "shared" / "datasets" / "biotacsp-dos" / "csvs"


def _as_other_lab(ds: Dataset, mask, unit: tuple[str, str], gain: float) -> Dataset:
    """The recordings of ``ds`` where ``mask`` holds, as another lab's sensor would give them:
    another unit name, samples times ``gain``."""
    part = subset(ds, mask)
    rec = part.recordings.assign(sensor_type=unit[0], sensor_instance=unit[1])
    return Dataset(rec, {k: v * gain for k, v in part.samples.items()})


@pytest.mark.slow
@pytest.mark.skipif(not DOS.is_dir(), reason=f"BioTacSP-DoS not found at {DOS}")
def test_real_recordings_across_labs_of_different_gain(tmp_path):
    """BioTacSP-DoS split by object into two "labs", the second's sensor named BioTac th and
    reading 1/500 of the counts: a type-only map finds the training finger, the raw threshold
    carries the first lab's scale and per-unit normalization bridges it; the material holdout
    has nothing to compare (no object on both sides); a sensor at another rate is refused."""
    from slipbench.data.importers import biotacsp_dos

    dos = read_dataset(biotacsp_dos(DOS, tmp_path / "dos"))
    first = dos.recordings["material"].isin(
        ["bottle", "brush", "bubbles", "cardboard", "case", "hd"]
    )
    ds = combine(
        subset(dos, first),
        _as_other_lab(dos, ~first, ("BioTac", "th"), 0.002),
        parse_sensor_map(["BioTac=BioTacSP"]),
    )
    assert json.loads(ds.origin["sensor_map"]) == {"BioTac:th": "BioTacSP:ff"}
    rows = {
        how: _run(WindowSize(windows=[50]), ds, tmp_path, how, out=how) for how in ("none", "unit")
    }
    raw, unit = rows["none"].iloc[0], rows["unit"].iloc[0]
    assert raw["status"] == "ok" and unit["status"] == "ok"
    assert unit["normalize_scale_train"] / unit["normalize_scale_test"] == pytest.approx(
        500, rel=0.3
    )
    assert raw["tp_rate"] < 0.1  # at 1/500 of the counts nothing crosses the threshold
    assert unit["balanced_accuracy"] > raw["balanced_accuracy"] + 0.1
    held = _run(MaterialHoldout(), ds, tmp_path, out="material")
    assert set(held["material"]) == set(dos.recordings.loc[~first, "material"])
    assert (held["status"] == "skipped").all()
    assert held["reason"].str.startswith("with and without are the same model").all()


def test_a_test_unit_at_another_rate_is_refused(tmp_path):
    a = lab(tmp_path, "a", ("BioTacSP", "ff"), 1.0)
    b = lab(tmp_path, "b", ("BioTacSP", "ff"), 1.0, seed=1)
    slow = Dataset(b.recordings.assign(sampling_rate_hz=100.0), b.samples)
    with pytest.raises(
        UsageError,
        match="sampled at 100 Hz, the training unit BioTacSP:ff it is tested as at 1000 Hz",
    ):
        combine(a, slow)
