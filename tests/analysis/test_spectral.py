"""The spectral analysis: a known band is found, the KS shortcut equals scipy, runs repeat
exactly, and the command writes its outputs or fails cleanly with exit code 2."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from scipy.stats import ks_2samp

from slipbench.analysis.spectral import (
    analyze,
    analyze_pools,
    ks_2samp_last_axis,
    significant_bands,
)
from slipbench.app.options import parse_params
from slipbench.engine.registry import detectors
from slipbench.errors import UsageError

FS = 500
BAND = (50.0, 80.0)


def two_pools(k: int, gain: float, seed: int = 0) -> np.ndarray:
    """(2, k, FS) one-second windows of white noise; the slip pool (index 1) gets extra noise
    inside BAND only, so the classes differ there and nowhere else."""
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((2, k, FS))
    extra = np.fft.rfft(rng.standard_normal((k, FS)), axis=-1)
    freqs = np.fft.rfftfreq(FS, 1 / FS)
    extra[:, (freqs < BAND[0]) | (freqs > BAND[1])] = 0
    x[1] += gain * np.fft.irfft(extra, FS, axis=-1)
    return x.astype(np.float32)


def test_a_known_band_is_found():
    x = two_pools(2000, gain=2.0)
    result = analyze_pools(x[0], x[1], FS, repeats=100, seed=0)
    t = result.table
    assert len(t) == FS // 2 + 1 and t["freq_hz"].iloc[-1] == FS / 2
    inside = t["freq_hz"].between(*BAND)
    assert t.loc[inside, "significance"].min() >= 0.95
    # outside, the classes are the same: the share of rejections is the test's false-rejection rate
    # (at most alpha for the exact, slightly conservative test, a little more from the finite pools)
    outside = t.loc[~inside, "significance"]
    assert 0.01 < outside.mean() < 0.08 and outside.max() < 0.3
    assert result.bands == [BAND] and result.best_band == BAND
    # amplitudes: slip above non-slip inside the band, the same outside
    assert (t.loc[inside, "slip_mean"] > 1.5 * t.loc[inside, "nonslip_mean"]).all()
    ratio = t.loc[~inside, "slip_mean"] / t.loc[~inside, "nonslip_mean"]
    assert ratio.between(0.9, 1.1).all()
    assert (t["nonslip_lo"] <= t["nonslip_mean"]).all() and (
        t["nonslip_mean"] <= t["nonslip_hi"]
    ).all()


def test_identical_classes_give_no_band():
    x = two_pools(2000, gain=0.0)
    result = analyze_pools(x[0], x[1], FS, n_boot=50, repeats=40, seed=1)
    assert result.bands == [] and result.best_band is None
    assert result.table["significance"].mean() < 0.08


def test_segments_join_into_one_second_sequences():
    x = two_pools(400, gain=2.0)
    short = x[:, :, :100].reshape(2, -1, 100)  # shorter windows, five per sequence
    result = analyze_pools(short[0], short[1], FS, repeats=20, seed=0)
    t = result.table
    assert len(t) == FS // 2 + 1
    assert t.loc[t["freq_hz"].between(55, 75), "significance"].min() >= 0.95
    assert result.params["segment_samples"] == 100 and result.params["sequence_samples"] == FS


def test_vectorised_ks_equals_scipy():
    rng = np.random.default_rng(0)
    a = rng.standard_normal((6, 7, 100))
    b = rng.standard_normal((6, 7, 100)) + np.linspace(0, 1, 7)[:, None]
    stat, p = ks_2samp_last_axis(a, b)
    ref = ks_2samp(a, b, axis=-1)
    np.testing.assert_array_equal(stat, ref.statistic)
    np.testing.assert_allclose(p, ref.pvalue, rtol=1e-12)
    # ties (bootstrap samples repeat values) and unequal sizes
    a = rng.integers(0, 8, (40, 30)).astype(float)
    b = rng.integers(0, 10, (40, 17)).astype(float)
    stat, p = ks_2samp_last_axis(a, b)
    ref = ks_2samp(a, b, axis=-1)
    np.testing.assert_allclose(stat, ref.statistic, rtol=1e-12)
    np.testing.assert_allclose(p, ref.pvalue, rtol=1e-12)


def test_band_definition_merges_small_gaps():
    freqs = np.arange(20.0)
    sig = np.zeros(20)
    sig[[1, 2, 3, 6, 7, 15]] = 1.0
    assert significant_bands(freqs, sig, 0.95, merge_hz=2) == [(1.0, 3.0), (6.0, 7.0), (15.0, 15.0)]
    assert significant_bands(freqs, sig, 0.95, merge_hz=3) == [(1.0, 7.0), (15.0, 15.0)]


def test_seeded_and_deterministic(small):
    kwargs = dict(segment=100, n_boot=30, repeats=10)
    first = analyze(small, "OptoForce20", "index", seed=3, **kwargs)
    again = analyze(small, "OptoForce20", "index", seed=3, **kwargs)
    other = analyze(small, "OptoForce20", "index", seed=4, **kwargs)
    pd.testing.assert_frame_equal(first.table, again.table)
    assert first.summary() == again.summary()
    assert not first.table.equals(other.table)
    assert first.params["sensor_type"] == "OptoForce20" and first.params["windows_slip"] > 0


def test_bad_parameters_are_named(small):
    with pytest.raises(UsageError, match="n_boot must be"):
        analyze(small, "Nano17", segment=100, n_boot=1)
    with pytest.raises(UsageError, match=r"segment must be an int in \[1, 1000\]"):
        analyze(small, "Nano17", segment=5000)


@pytest.mark.slow
def test_command_writes_figure_table_and_band(small_path, tmp_path, cli):
    out = tmp_path / "spectral"
    argv = [
        "spectral",
        "--dataset",
        str(small_path),
        "--sensor",
        "Nano17",
        "--sensor",
        "BioTacSP",
        "--instance",
        "index",
        "--segment",
        "100",
        "--boot",
        "30",
        "--repeats",
        "10",
        "--out",
        str(out),
    ]
    code, text, err = cli(argv)
    assert code == 0, err
    for stem in ("Nano17-index", "BioTacSP-index"):
        for suffix in (".png", ".pdf", ".csv", ".json"):
            assert (out / f"{stem}{suffix}").stat().st_size > 0
    table = pd.read_csv(out / "BioTacSP-index.csv")
    assert table["freq_hz"].iloc[-1] == 425 and {"significance", "slip_mean", "nonslip_hi"} <= set(
        table.columns
    )
    summary = json.loads((out / "Nano17-index.json").read_text())
    assert (
        summary["sensor_type"] == "Nano17"
        and summary["repeats"] == 10
        and summary["segment_samples"] == 100
    )
    # the printed band is in the form `evaluate --param` reads, and holweg takes it
    line = next(
        line for line in text.splitlines() if line.startswith("Nano17-index: most significant band")
    )
    param = line.rsplit("--param ", 1)[1]
    band = parse_params((param,))["band"]
    assert band == summary["most_significant_band"]
    detectors.get("holweg")().set_params(band=band)


@pytest.mark.slow
def test_unknown_sensor_or_instance_exits_2_and_writes_nothing(small_path, tmp_path, cli):
    out = tmp_path / "spectral"
    code, _, err = cli(
        [
            "spectral",
            "--dataset",
            str(small_path),
            "--sensor",
            "Nano17",
            "--sensor",
            "GelSight",
            "--segment",
            "100",
            "--repeats",
            "2",
            "--out",
            str(out),
        ]
    )
    assert code == 2 and "unknown sensor 'GelSight'" in err
    assert (
        "BioTacSP, Nano17, OptoForce20" in err and "Traceback" not in err
    )  # recordings in canonical (id) order
    assert not out.exists()
    code, _, err = cli(
        ["spectral", "--dataset", str(small_path), "--sensor", "BioTacSP", "--instance", "little"]
    )
    assert code == 2 and "BioTacSP has no instance 'little'; its instances: index, middle" in err


def test_recordings_shorter_than_a_segment_are_refused(small_path, cli):
    # at scale 0.02 a slip recording holds half a second: one contiguous second does not fit
    code, _, err = cli(
        ["spectral", "--dataset", str(small_path), "--sensor", "Nano17", "--instance", "index"]
    )
    assert code == 2 and "holds a 1000-sample segment" in err and "--segment" in err


# ----------------------------------------------------------------------------- without peeking
def _runner_sides(ds, sensor: str, split: str, seed: int, window: int):
    """The train and test windows (positions) the runner plans for a cell at ``window`` of each
    instance of ``sensor``."""
    from slipbench.data.signals import Signals
    from slipbench.engine.plan import Run, make_plan
    from slipbench.protocols.window_size import WindowSize

    run = Run("holweg", WindowSize(windows=[window]), split, seed)
    cells = [c for c in run.cells(ds.recordings) if c.key["sensor_type"] == sensor]
    plan = make_plan(Signals.from_dataset(ds), [(run, cells)], "f", set())
    return [(pc.train, pc.test) for pc in plan.cells]


def _keep_only(ds, windows: list, window: int, seed: int):
    """``ds`` with every reading outside ``windows`` replaced by large noise. A window of s at
    position i holds readings i * window ... (i + 1) * window of its recording."""
    from slipbench.data.format import Dataset

    ids = ds.recordings["recording_id"].to_numpy()
    keep = {rid: np.zeros(len(x), bool) for rid, x in ds.samples.items()}
    for w in windows:
        for r, i in zip(w.recording, w.index):
            keep[ids[r]][i * window : (i + 1) * window + 1] = True
    rng = np.random.default_rng(seed)
    samples = {
        rid: np.where(keep[rid][:, None], x, 1e6 * rng.standard_normal(x.shape))
        for rid, x in ds.samples.items()
    }
    return Dataset(ds.recordings, samples, ds.slip_labels)


@pytest.mark.slow
@pytest.mark.parametrize("split", ["paper", "grouped"])
def test_train_only_never_reads_a_test_window(small, split):
    """Poison every reading outside the runner's training windows (its test windows among them):
    the training-side analysis is unchanged; poisoning one training window changes it, and the
    analysis of every recording reads the poison."""
    kwargs = dict(segment=50, n_boot=30, repeats=10, seed=3)
    sides = _runner_sides(small, "OptoForce20", split, 3, 50)
    train = [t for t, _ in sides]
    poisoned = _keep_only(small, train, 50, seed=0)
    # the poison covers every test window (the split keeps the sides apart)
    for _, test in sides:
        ids = small.recordings["recording_id"].to_numpy()
        for r, i in zip(test.recording, test.index):
            assert (
                poisoned.samples[ids[r]][i * 50 + 1 : (i + 1) * 50]
                != small.samples[ids[r]][i * 50 + 1 : (i + 1) * 50]
            ).all()

    clean = analyze(small, "OptoForce20", split=split, **kwargs)
    again = analyze(poisoned, "OptoForce20", split=split, **kwargs)
    pd.testing.assert_frame_equal(clean.table, again.table)
    assert clean.bands == again.bands and clean.best_band == again.best_band
    assert clean.params["train_split"] == split and clean.params["segment_samples"] == 50
    assert clean.params["windows_slip"] + clean.params["windows_nonslip"] == sum(
        len(t) for t in train
    )

    one_less = [
        train[0].take(np.arange(1, len(train[0]))),
        *train[1:],
    ]  # poison one training window too
    touched = analyze(_keep_only(small, one_less, 50, seed=0), "OptoForce20", split=split, **kwargs)
    assert not touched.table.equals(clean.table)
    everything = dict(kwargs, segment=100)
    assert not analyze(poisoned, "OptoForce20", **everything).table.equals(
        analyze(small, "OptoForce20", **everything).table
    )


@pytest.mark.slow
def test_train_only_from_the_command_line(small_path, tmp_path, cli):
    out = tmp_path / "spectral"
    base = [
        "spectral",
        "--dataset",
        str(small_path),
        "--sensor",
        "BioTacSP",
        "--instance",
        "index",
        "--boot",
        "30",
        "--repeats",
        "10",
        "--out",
        str(out),
        "--seed",
        "2",
    ]
    code, text, err = cli([*base, "--train-only", "--split", "grouped"])
    assert code == 0, err
    summary = json.loads((out / "BioTacSP-index.json").read_text())
    assert (
        summary["train_split"] == "grouped"
        and summary["segment_samples"] == 50
        and summary["seed"] == 2
    )
    assert "training side only (grouped split, seed 2, window 50)" in text
    # a split without --train-only would be silently ignored: refused instead
    code, _, err = cli([*base, "--split", "grouped"])
    assert code == 2 and "add --train-only" in err
    # a window that only free-space recordings hold: the runner's reason, for these windows, exit 2
    code, _, err = cli([*base, "--train-only", "--segment", "850"])
    assert code == 2 and "Traceback" not in err
    assert (
        "BioTacSP index, paper split at window 850: balancing needs slip and non-slip windows"
        in err
    )
