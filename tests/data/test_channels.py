"""The channels input on the data side: windows of the raw channels are the readings under the
univariate windows, decimated to the readings a slower sensor takes, filtered by the same
anti-aliasing filter, and standardized by statistics the caller chooses."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slipbench.data.signals import (
    Signals,
    channel_scales,
    robust_scale,
    standardized,
    univariate,
)
from slipbench.errors import UsageError


def signals_of(*recordings: np.ndarray, rate: float = 1000.0) -> Signals:
    parts = [univariate(a) for a in recordings]
    rec = pd.DataFrame(
        {
            "recording_id": [f"r{i}" for i in range(len(recordings))],
            "sampling_rate_hz": rate,
            "scenario": "slip",
            "sensor_type": "S",
            "sensor_instance": [f"u{i}" for i in range(len(recordings))],
        }
    )
    return Signals(
        np.concatenate(parts),
        np.r_[0, np.cumsum([len(p) for p in parts])].astype(np.int64),
        rec,
        np.ones(sum(len(p) for p in parts), np.int8),
        channels=list(recordings),
    )


@settings(max_examples=50, deadline=None)
@given(
    window=st.integers(5, 40),
    factor=st.integers(1, 7),
    channels=st.integers(1, 5),
    decimation=st.sampled_from(["plain", "lag"]),
    seed=st.integers(0, 2**16),
)
def test_channel_windows_hold_the_readings_of_the_univariate_windows(
    window, factor, channels, decimation, seed
):
    """The norm of a channel window's readings, differenced, is the univariate window: at the
    full rate and after either decimation (each keeps the readings its difference ends on)."""
    if window // factor < 2:
        return
    rng = np.random.default_rng(seed)
    a = (100 + rng.standard_normal((3 * window + 4, channels)).cumsum(axis=0)).astype(np.float32)
    signals = signals_of(a)
    windows = signals.windows(window)
    full = windows.__class__(
        signals.channel_values(windows, window),
        windows.recording,
        windows.index,
        windows.recordings,
        windows.labels,
    )
    assert full.x.shape == (3, window, channels)
    uni = windows if factor == 1 else windows.downsample(factor, decimation)
    ch = full if factor == 1 else full.downsample(factor, decimation)
    assert ch.x.shape == (*uni.x.shape, channels)
    norms = np.linalg.norm(ch.x.astype(np.float64), axis=2)
    if factor == 1 or decimation == "lag":  # the slower sensor's own lag-one difference
        np.testing.assert_allclose(np.diff(norms, axis=1), uni.x[:, 1:], rtol=1e-4, atol=1e-3)
    else:  # every k-th full-rate difference ends on the reading kept
        for i in range(3):
            before = np.linalg.norm(a[i * window + np.arange(uni.x.shape[1]) * factor], axis=1)
            np.testing.assert_allclose(norms[i] - before, uni.x[i], rtol=1e-4, atol=1e-3)


def test_antialiased_channels_filter_as_the_univariate_path_does():
    """One channel that never goes negative: its norm is itself, so filtering the channel and
    differencing equals filtering the difference (the filter is linear, both at rest)."""
    rng = np.random.default_rng(0)
    a = (1000 + rng.standard_normal((400, 1)).cumsum(axis=0)).astype(np.float64)
    signals = signals_of(a)
    low = signals.antialiased_channels(4)[0][:, 0].astype(np.float64)
    expected = signals.antialiased(4).buffer
    np.testing.assert_allclose(np.diff(low), expected, rtol=1e-3, atol=1e-3)


def test_recordings_of_different_channel_counts_form_no_window_array():
    rng = np.random.default_rng(1)
    signals = signals_of(rng.normal(size=(50, 3)), rng.normal(size=(50, 6)))
    with pytest.raises(UsageError, match=r"\[3, 6\] channels"):
        signals.channel_values(signals.windows(10), 10)


def test_standardized_uses_the_given_statistics_per_channel():
    """Scales from the training windows, applied as they are to others; an electrode resting
    at thousands of counts keeps its one-count changes."""
    rng = np.random.default_rng(2)
    train = np.stack([3000 + rng.normal(0, 2, (40, 20)), rng.normal(0, 0.01, (40, 20))], axis=2)
    scales = channel_scales(train.astype(np.float32))
    assert scales.shape == (2, 2)
    assert scales[0] == pytest.approx(robust_scale(train[..., 0].astype(np.float32)))
    z = standardized(train.astype(np.float32), scales)
    assert abs(np.median(z)) < 0.2 and 0.7 < np.median(np.abs(z)) * 1.4826 < 1.3
    other = np.full((1, 2, 2), [3001.0, 0.0], dtype=np.float32)
    np.testing.assert_allclose(
        standardized(other, scales)[0, 0],
        (np.array([3001.0, 0.0]) - scales[:, 0]) / scales[:, 1],
        rtol=1e-5,
    )


def test_normalizing_keeps_which_recordings_carry_labels():
    """A normalized signal still knows which recordings carry per-sample labels: labelling by
    samples must not fall back to the scenario for the others (it did: the flag was lost)."""
    rng = np.random.default_rng(3)
    signals = signals_of(rng.normal(size=(60, 2)), rng.normal(size=(60, 2)))
    signals.labelled = np.array([True, False])
    normalized, _ = signals.normalized(np.array([0, 1]), np.ones(2, bool))
    np.testing.assert_array_equal(normalized.labelled, [True, False])
    assert normalized.channels is signals.channels
    kept = normalized.windows(10, labelling="majority")
    assert set(kept.recording) == {0}
