"""TorchDetector: a plugin is a small module and its parameters, and passes the conformance kit."""

from __future__ import annotations

import numpy as np
import pytest

from slipbench.params import Interval
from slipbench.testing import parametrize_with_checks, toy_channel_windows, toy_windows
from slipbench.torch import TorchDetector

torch = pytest.importorskip("torch")


# docs/guides/plugins.md shows this class: the documented plugin is the tested one
# --8<-- [start:tinycnn]
class TinyCNN(TorchDetector):
    """One convolution, global average pooling, one logit."""

    _parameter_constraints = {**TorchDetector.TRAINING_CONSTRAINTS, "filters": Interval(int, 1, 64)}
    check_params = {"max_epochs": 2, "patience": 1}  # fast conformance checks

    def __init__(
        self,
        filters=8,
        batch_size=64,
        learning_rate=1e-2,
        max_epochs=20,
        patience=3,
        validation_fraction=0.2,
        device="auto",
    ):
        super().__init__(
            batch_size, learning_rate, max_epochs, patience, validation_fraction, device
        )
        self.filters = filters

    def build(self, window_length, n_channels):  # (batch, n_channels, window) -> (batch, 1)
        from torch import nn  # imported where the model is built: the plugin loads without torch

        return nn.Sequential(
            nn.Conv1d(n_channels, self.filters, 5, padding=2),
            nn.ReLU(),
            nn.AdaptiveAvgPool1d(1),
            nn.Flatten(),
            nn.Linear(self.filters, 1),
        )


# --8<-- [end:tinycnn]


@parametrize_with_checks([TinyCNN()])
def test_a_small_torch_plugin_conforms(plugin, check):
    check(plugin)


def test_learns_saves_without_pickle_and_reloads_the_same_scores(tmp_path):
    x, y = toy_windows(n=200, length=40, seed=1)
    det = TinyCNN(max_epochs=15).fit(x, y, seed=3, groups=np.arange(200) // 8)
    assert (det.predict(x) == y).mean() > 0.9
    assert det.fitted_choices()["validation_by"] == "trial"
    det.save(tmp_path / "m.npz")
    with np.load(tmp_path / "m.npz", allow_pickle=False) as f:  # plain arrays only
        assert any(k.startswith("state_") for k in f.files)
    np.testing.assert_array_equal(
        TinyCNN.load(tmp_path / "m.npz").predict_proba(x), det.predict_proba(x)
    )


def test_same_seed_same_model_and_the_callers_rng_untouched():
    x, y = toy_windows(n=80, length=20, seed=0)
    torch.manual_seed(123)
    before = torch.rand(3)
    torch.manual_seed(123)
    a = TinyCNN(max_epochs=3).fit(x, y, seed=5).predict_proba(x)
    after = torch.rand(3)
    b = TinyCNN(max_epochs=3).fit(x, y, seed=5).predict_proba(x)
    c = TinyCNN(max_epochs=3).fit(x, y, seed=6).predict_proba(x)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert torch.equal(before, after)


def test_validation_by_window_is_said_when_trials_cannot_give_both_classes():
    x, y = toy_windows(n=60, length=20, seed=0)
    one_trial = np.zeros(60)
    det = TinyCNN(max_epochs=2).fit(x, y, seed=0, groups=one_trial)
    assert det.fitted_choices()["validation_by"] == "window"


def test_a_build_that_is_not_a_module_is_refused():
    class Broken(TinyCNN):
        def build(self, window_length, n_channels):
            return lambda x: x.sum(1)

    from slipbench.errors import UsageError

    x, y = toy_windows(n=40, length=20, seed=0)
    with pytest.raises(UsageError, match="not a torch.nn.Module"):
        Broken().fit(x, y)


def test_windows_of_channels_reach_the_network_as_its_input_channels():
    built = []

    class Seen(TinyCNN):
        def build(self, window_length, n_channels):
            built.append((window_length, n_channels))
            return super().build(window_length, n_channels)

    x, y = toy_channel_windows(n=200, length=40, channels=5, seed=1)  # slip: channel 0's burst
    det = Seen(max_epochs=15).fit(x, y, seed=3, groups=np.arange(200) // 8)
    assert built[0] == (40, 5) and det.n_channels_ == 5
    assert det.mean_.shape == det.std_.shape == (5,)  # each channel its own scale
    assert (det.predict(x) == y).mean() > 0.9
    Seen(max_epochs=1).fit(x[:, :, 0], y, seed=0)
    assert built[-1] == (40, 1)  # univariate windows: one channel


def test_a_network_for_the_univariate_signal_only_refuses_channels():
    class Univariate(TinyCNN):
        inputs = ("univariate",)

    x, y = toy_channel_windows(n=40, length=20)
    from slipbench.errors import UsageError

    with pytest.raises(UsageError, match="takes univariate windows"):
        Univariate().fit(x, y)
