"""Holweg's threshold rule and the spectral helpers it stands on."""

from __future__ import annotations

import numpy as np
import pytest

from slipbench.detectors.holweg import Holweg
from slipbench.errors import UsageError
from slipbench.spectra import amplitude_spectrum, best_threshold


def test_amplitude_spectrum_reads_a_sines_amplitude():
    fs, n = 1000.0, 1000
    t = np.arange(n) / fs
    freqs, amp = amplitude_spectrum((0.5 + 2.0 * np.sin(2 * np.pi * 60 * t))[None, :], fs)
    assert freqs[60] == 60
    assert amp[0, 60] == pytest.approx(2.0, rel=1e-6)
    assert amp[0, 0] == pytest.approx(0.5, rel=1e-6)


def test_threshold_sits_at_the_largest_cdf_separation():
    values = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0])
    y = np.array([0, 0, 0, 1, 0, 1, 1, 1])
    threshold, direction, separation = best_threshold(values, y)
    # at t = 3: all but one non-slip below (F=3/4), no slip below (F=0) -> 0.75; t = 5 gives 1 - 1/4 = 0.75 too,
    # the first maximum is kept
    assert direction == 1 and separation == pytest.approx(0.75)
    assert 3.0 < threshold < 4.0
    flipped = best_threshold(-values, y)
    assert flipped[1] == -1 and flipped[2] == pytest.approx(0.75)


def _tones(n, rng, fs=1000.0, w=50):
    """Slip windows carry a 60 Hz tone, non-slip windows only noise."""
    t = np.arange(w) / fs
    y = rng.integers(0, 2, n)
    x = rng.normal(0, 1, (n, w)) + 3 * y[:, None] * np.sin(
        2 * np.pi * 60 * t + rng.uniform(0, 6, (n, 1))
    )
    return x.astype(np.float32), y


def test_holweg_finds_the_band_and_separates():
    rng = np.random.default_rng(0)
    x, y = _tones(2000, rng)
    det = Holweg().fit(x, y, sampling_rate=1000.0)
    assert det.band_hz_[0] <= 60 <= det.band_hz_[1]
    xt, yt = _tones(2000, rng)
    assert (det.predict(xt) == yt).mean() > 0.95
    p = det.predict_proba(xt)
    assert ((p >= 0) & (p <= 1)).all()


def test_holweg_fixed_band_must_hold_a_bin():
    rng = np.random.default_rng(0)
    x, y = _tones(200, rng)
    with pytest.raises(UsageError, match="holds no FFT bin"):
        Holweg(band=(600, 900)).fit(x, y, sampling_rate=1000.0)
    assert Holweg(band=(40, 80)).fit(x, y, sampling_rate=1000.0).band_hz_ == (40.0, 80.0)
    # 5-sample windows have bins every 200 Hz: the 0-100 Hz band keeps the bins whose cells meet it
    assert Holweg(band=(38, 79)).fit(x[:, :5], y, sampling_rate=1000.0).band_hz_ == (0.0, 0.0)
    assert Holweg(band=(38, 120)).fit(x[:, :5], y, sampling_rate=1000.0).band_hz_ == (0.0, 200.0)


def test_holweg_parameter_validation_message():
    with pytest.raises(
        UsageError,
        match=r"The 'band' parameter of Holweg must be None or a \(low_hz, high_hz\) pair.*Got \(5, 1\) instead",
    ):
        Holweg(band=(5, 1)).fit(np.zeros((4, 10)), [0, 1, 0, 1])
