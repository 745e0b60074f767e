"""The detector contract that the base class enforces for every plugin."""

from __future__ import annotations

import numpy as np
import pytest

from slipbench.base import BaseDetector, NotFittedError, clone
from slipbench.detectors.holweg import Holweg
from slipbench.errors import UsageError


def test_get_params_and_clone():
    det = Holweg(band=(0, 100), keep=0.5)
    assert det.get_params() == {"band": (0, 100), "keep": 0.5}
    copy = clone(det)
    assert copy is not det and copy.get_params() == det.get_params()
    with pytest.raises(UsageError, match="has no parameter 'nope'; its parameters: band, keep"):
        det.set_params(nope=1)


def test_input_is_checked_once_in_the_base_class():
    x = np.random.default_rng(0).normal(size=(20, 10)).astype(np.float32)
    y = np.r_[np.zeros(10), np.ones(10)].astype(int)
    with pytest.raises(NotFittedError):
        Holweg().predict(x)
    bad = x.copy()
    bad[3, 4] = np.nan
    with pytest.raises(UsageError, match="window 3, sample 4"):
        Holweg().fit(bad, y)
    with pytest.raises(UsageError, match="only class 1"):
        Holweg().fit(x, np.ones(20, int))
    with pytest.raises(UsageError, match="at least 5 samples"):
        Holweg().fit(x[:, :4], y)
    det = Holweg().fit(x, y)
    with pytest.raises(UsageError, match="fitted on windows of 10 samples, got 12"):
        det.predict(np.zeros((2, 12)))


def test_a_minimal_plugin_gets_the_contract_for_free():
    class Mean(BaseDetector):
        name = "mean"

        def __init__(self, offset=0.0):
            self.offset = offset

        def _fit(self, x, y, seed):
            self.cut_ = x.mean(axis=1)[y == 1].mean()

        def _predict_proba(self, x):
            return (x.mean(axis=1) + self.offset > self.cut_).astype(float)

    x = np.r_[np.zeros((5, 6)), np.ones((5, 6))]
    det = Mean(offset=0.1).fit(x, np.r_[np.zeros(5), np.ones(5)].astype(int))
    assert det.predict(x).tolist() == [0] * 5 + [1] * 5
    assert det.sampling_rate_ == 1000.0 and det.window_length_ == 6


class _Loudness(BaseDetector):
    """Mean absolute value over a window (and its channels) against a training median."""

    inputs = ("univariate", "channels")

    def _fit(self, x, y, seed):
        self.cut_ = float(np.median(np.abs(x).reshape(len(x), -1).mean(axis=1)))

    def _predict_proba(self, x):
        return (np.abs(x).reshape(len(x), -1).mean(axis=1) > self.cut_).astype(float)


class _ChannelsOnly(_Loudness):
    inputs = ("channels",)


def test_a_univariate_detector_refuses_windows_of_channels_naming_shape_and_inputs():
    x = np.random.default_rng(0).normal(size=(20, 10, 3)).astype(np.float32)
    y = np.r_[np.zeros(10), np.ones(10)].astype(int)
    with pytest.raises(
        UsageError,
        match=r"detector 'holweg' takes univariate windows \(n_windows, window_length\) "
        r"\(inputs: univariate\), got an array of shape \(20, 10, 3\); windows of channels "
        r"need a detector that declares 'channels' in its inputs",
    ):
        Holweg().fit(x, y)
    fitted = Holweg().fit(x[:, :, 0], y)
    assert fitted.n_channels_ == 0
    with pytest.raises(UsageError, match=r"shape \(20, 10, 3\)"):
        fitted.predict_proba(x)
    with pytest.raises(
        UsageError, match=r"takes windows of channels .* got an array of shape \(20, 10\)"
    ):
        _ChannelsOnly().fit(x[:, :, 0], y)
    with pytest.raises(UsageError, match=r"shape \(20,\)"):
        _Loudness().fit(x[:, 0, 0], y)


def test_windows_of_channels_fit_predict_save_and_load(tmp_path):
    rng = np.random.default_rng(0)
    x = (
        rng.normal(size=(20, 10, 3)).astype(np.float32)
        * np.r_[np.ones(10), 3 * np.ones(10)][:, None, None]
    )
    y = np.r_[np.zeros(10), np.ones(10)].astype(int)
    det = _Loudness().fit(x, y)
    assert det.n_channels_ == 3 and det.window_length_ == 10
    assert det.predict(x).tolist() == y.tolist()
    with pytest.raises(
        UsageError, match=r"fitted on windows of 3 channels .* got windows of shape \(20, 10, 2\)"
    ):
        det.predict_proba(x[:, :, :2])
    with pytest.raises(
        UsageError, match=r"fitted on windows of 3 channels .* got windows of shape \(20, 10\)"
    ):
        det.predict_proba(x[:, :, 0])
    with pytest.raises(UsageError, match="fitted on univariate windows"):
        _Loudness().fit(x[:, :, 0], y).predict_proba(x)
    bad = x.copy()
    bad[4, 2, 1] = np.inf
    with pytest.raises(UsageError, match="window 4, sample 2, channel 1"):
        _Loudness().fit(bad, y)
    with pytest.raises(UsageError, match="at least one channel"):
        _Loudness().fit(x[:, :, :0], y)
    det.save(tmp_path / "d.npz")
    again = _Loudness.load(tmp_path / "d.npz")
    assert again.n_channels_ == 3 and np.array_equal(again.predict_proba(x), det.predict_proba(x))


def test_a_fit_reports_its_epochs_to_whoever_listens():
    """The LSTM says how far its fit has come after each epoch; nobody listening costs nothing."""
    from slipbench.base import listening
    from slipbench.detectors.lstm import LSTM

    rng = np.random.default_rng(0)
    y = np.repeat([0, 1], 40)
    x = (rng.normal(0, 1, (80, 10)) * (1 + y[:, None])).astype(np.float32)
    heard: list[dict] = []
    with listening(heard.append):
        LSTM(max_epochs=(2, 1), learning_rates=(0.01, 0.001), hidden_size=4).fit(x, y)
    assert [r["step"] for r in heard] == [1, 2, 3]
    assert {r["total"] for r in heard} == {3} and {r["unit"] for r in heard} == {"epoch"}
    assert {r["detector"] for r in heard} == {"lstm"} and all(r["loss"] > 0 for r in heard)
    LSTM(max_epochs=1, hidden_size=4).fit(x, y)  # outside the block: nothing heard
    assert len(heard) == 3
