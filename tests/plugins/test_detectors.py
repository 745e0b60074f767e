"""Detector-specific behaviour (bandpass, wavelet-svm, minirocket on both inputs), and a detector that raises
during a run."""

from __future__ import annotations

import numpy as np
import pytest
import toys

from slipbench.base import BaseDetector
from slipbench.detectors.bandpass import effective_band
from slipbench.detectors.wavelet_svm import wavelet_and_level
from slipbench.engine.registry import Registry, detectors, protocols
from slipbench.engine.runner import Run, evaluate
from slipbench.store.results import ResultsStore
from slipbench.testing import check_detector, toy_channel_windows, toy_windows


@pytest.mark.parametrize(
    "rate, band, fallback",
    [
        (1000.0, (50.0, 400.0), False),  # as asked
        (500.0, (50.0, 225.0), False),  # top clipped to 0.9 Nyquist
        (62.5, (62.5 / 8, 0.9 * 31.25), True),  # the whole band above Nyquist: the fallback
    ],
)
def test_bandpass_clips_the_band_and_falls_back(rate, band, fallback):
    assert effective_band((50, 400), rate) == (pytest.approx(band), fallback)
    x, y = toy_windows(100, 30)
    d = detectors.get("bandpass")().fit(x, y, sampling_rate=rate)
    assert d.band_hz_ == pytest.approx(band) and d.band_fallback_ is fallback
    # what ran otherwise than asked is declared, as what ran
    if rate == 1000.0:
        assert d.overrides() == {}
    else:
        ((ran, why),) = d.overrides().values()
        assert ran == pytest.approx(band, abs=1e-3) and ("above Nyquist" in why) is fallback


def test_holweg_declares_a_band_cut_at_nyquist():
    x, y = toy_windows(100, 30)
    assert detectors.get("holweg")(band=(40, 80)).fit(x, y, sampling_rate=1000.0).overrides() == {}
    d = detectors.get("holweg")(band=(40, 800)).fit(x, y, sampling_rate=1000.0)
    assert d.overrides() == {
        "band": ([40.0, 500.0], "its top above Nyquist 500 Hz, where bins end")
    }


def test_bandpass_separates_a_burst_in_its_band():
    x, y = toy_windows(400, 50)  # slip adds a 60 Hz burst
    d = detectors.get("bandpass")(band=(40, 80)).fit(x[:200], y[:200])
    assert (d.predict(x[200:]) == y[200:]).mean() > 0.9


@pytest.mark.parametrize(
    "length, wavelet, level", [(5, "haar", 2), (50, "db4", 2), (200, "db4", 4)]
)
def test_wavelet_and_level_adapt_to_short_windows(length, wavelet, level):
    assert wavelet_and_level(length, "db4", 4) == (wavelet, level)


def test_wavelet_svm_concatenates_each_channels_features_and_learns_from_channels():
    from slipbench.detectors.wavelet_svm import WaveletSVM

    x, y = toy_channel_windows(400, 50, channels=4)  # slip: a burst in channel 0 only
    det = WaveletSVM(n_components=100).fit(x[:200], y[:200], seed=0)
    assert det.n_channels_ == 4 and det.mean_.shape == (4 * 4 * (det.level_ + 1),)
    assert (det.predict(x[200:]) == y[200:]).mean() > 0.9
    det.mean_, det.std_ = 0.0, 1.0  # the raw log statistics
    each = det._features(x[:10])
    for c in range(4):  # channel c's block: the univariate features of channel c
        np.testing.assert_allclose(
            each[:, c * 4 * (det.level_ + 1) : (c + 1) * 4 * (det.level_ + 1)],
            det._features(np.ascontiguousarray(x[:10, :, c])),
            rtol=1e-5,
        )


def test_minirocket_pads_short_windows():
    from slipbench.detectors.minirocket import _pad

    x = np.ones((3, 5), np.float32)
    padded = _pad(x)
    assert padded.shape == (3, 9) and (padded[:, :4] == 0).all() and (padded[:, 4:] == 1).all()
    assert _pad(np.ones((2, 12))).shape == (2, 12)


def test_minirocket_series_put_channels_before_time():
    from slipbench.detectors.minirocket import _series

    x = np.arange(2 * 5 * 3, dtype=np.float64).reshape(2, 5, 3)  # (n, length, channels)
    series = _series(x)
    assert series.shape == (2, 3, 9) and series.dtype == np.float32
    assert (series[:, :, :4] == 0).all() and (series[1, 2, 4:] == x[1, :, 2]).all()
    assert _series(x[:, :, 0]).shape == (2, 1, 9)


def test_minirocket_learns_a_burst_in_one_of_four_channels():
    pytest.importorskip("aeon")
    from slipbench.detectors.minirocket import MiniRocketDetector

    x, y = toy_channel_windows(400, 50, channels=4)  # slip: a burst in channel 0 only
    det = MiniRocketDetector(n_kernels=168).fit(x[:200], y[:200], seed=0)
    assert det.n_channels_ == 4 and set(det.channel_indices_) <= {0, 1, 2, 3}
    assert det.num_channels_.max() > 1  # kernels that sum several channels: the multivariate kind
    assert (det.predict(x[200:]) == y[200:]).mean() > 0.9


RAISES = toys.source(toys.Flaky)


@pytest.mark.slow
def test_a_folder_plugin_that_raises_in_fit_is_reported_and_the_run_goes_on(tmp_path, small):
    (tmp_path / "flaky.py").write_text(RAISES)
    reg = Registry("detector", BaseDetector, "slipbench.detectors")
    reg.add_folder(tmp_path)
    cls = reg.get("flaky")
    with pytest.raises(RuntimeError, match="diverged"):
        check_detector(cls())  # the suite tries 5-sample windows too
    run = Run(cls(), protocols.get("window-size")())
    rows = evaluate(small, run, ResultsStore(tmp_path / "out"), progress=False)
    failed, ok = rows[rows["status"] == "failed"], rows[rows["status"] == "ok"]
    assert len(failed) == len(rows[rows["window"] == 5]) > 0 and (failed["window"] == 5).all()
    assert (
        failed["reason"]
        .str.contains("detector 'flaky' raised: RuntimeError: diverged on short windows")
        .all()
    )
    assert len(ok) == len(rows) - len(failed) and (ok["window"] > 5).all()  # the run went on
