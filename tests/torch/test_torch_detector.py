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
    det = TinyCNN(max_epochs=4).fit(x, y, seed=3, groups=np.arange(200) // 8)
    assert (det.predict(x) == y).mean() > 0.9
    assert det.fitted_choices()["validation_by"] == "trial"
    det.save(tmp_path / "m.npz")
    with np.load(tmp_path / "m.npz", allow_pickle=False) as f:  # plain arrays only
        assert any(k.startswith("state_") for k in f.files)
    np.testing.assert_array_equal(
        TinyCNN.load(tmp_path / "m.npz").predict_proba(x), det.predict_proba(x)
    )


@pytest.mark.slow
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


@pytest.mark.slow
def test_windows_of_channels_reach_the_network_as_its_input_channels():
    built = []

    class Seen(TinyCNN):
        def build(self, window_length, n_channels):
            built.append((window_length, n_channels))
            return super().build(window_length, n_channels)

    x, y = toy_channel_windows(n=200, length=40, channels=5, seed=1)  # slip: channel 0's burst
    det = Seen(max_epochs=4).fit(x, y, seed=3, groups=np.arange(200) // 8)
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


# --- device="auto": measured where CUDA is present, cached, never "a GPU exists" ---------------
@pytest.fixture
def fake_cuda(monkeypatch, tmp_path):
    """CUDA present as far as the choice can tell, each device's step time as given, and the
    calls that measured them; the cache in a fresh folder."""
    monkeypatch.setenv("SLIPBENCH_CACHE", str(tmp_path))
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "get_device_name", lambda *a: "Fake GPU")
    timed: list[tuple[int, str]] = []
    seconds = {"cpu": 0.010, "cuda": 0.002}

    def step_seconds(self, device):
        timed.append((self.window_length_, device))
        return seconds[device]

    monkeypatch.setattr(TorchDetector, "_step_seconds", step_seconds)
    return seconds, timed


def test_auto_is_the_cpu_at_no_cost_without_cuda(monkeypatch):
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    monkeypatch.setattr(TorchDetector, "_step_seconds", lambda *a: pytest.fail("timed"))
    x, y = toy_windows(n=40, length=20, seed=0)
    choices = TinyCNN(max_epochs=1).fit(x, y).fitted_choices()
    assert (choices["device"], choices["device_why"]) == ("cpu", "auto: no CUDA device")


@pytest.mark.slow
def test_auto_takes_the_device_measured_faster_and_caches_it(fake_cuda):
    from slipbench.torch import device

    seconds, timed = fake_cuda
    key = {"detector": "x", "window_length": 50}
    chosen, why = device.choose("auto", key, lambda d: seconds[d])
    assert chosen == "cuda" and "2 ms per training step against 10 ms on cpu" in why
    # the GPU slower for this network and batch: the CPU, measured on first use, then cached
    seconds["cuda"] = 0.030
    x, y = toy_windows(n=40, length=20, seed=0)
    first = TinyCNN(max_epochs=1).fit(x, y).fitted_choices()
    assert first["device"] == "cpu" and "measured now" in first["device_why"]
    assert timed == [(20, "cpu"), (20, "cuda")]
    again = TinyCNN(max_epochs=1).fit(x, y, seed=1).fitted_choices()
    assert again["device"] == "cpu" and "cached in" in again["device_why"]
    assert len(timed) == 2  # the cache answered
    TinyCNN(max_epochs=1).fit(x[:, :10], y)  # another window length is another key
    assert timed[2:] == [(10, "cpu"), (10, "cuda")]
    # asked for, not measured
    assert TinyCNN(max_epochs=1, device="cpu").fit(x, y).fitted_choices()["device_why"] == "asked"
    assert len(timed) == 4


# --- epochs of a set size, the validation part, and what the engine judges there ----------------
def test_draws_pass_every_window_once_before_any_twice():
    from slipbench.torch.detector import _Draws

    draws = _Draws(np.arange(10), np.random.default_rng(0))
    taken = np.concatenate([draws.take(4) for _ in range(5)])
    assert sorted(taken[:10]) == sorted(taken[10:]) == list(range(10))


@pytest.mark.slow
def test_an_epoch_trains_windows_per_epoch_windows_whatever_the_set(monkeypatch):
    import slipbench.torch.detector as module

    seen: list[int] = []

    class Counted(TinyCNN):
        def build(self, window_length, n_channels):
            net = super().build(window_length, n_channels)
            net.register_forward_hook(
                lambda m, i, o: seen.append(len(i[0])) if m.training else None
            )
            return net

    x, y = toy_windows(n=200, length=20, seed=0)
    groups = np.arange(200) // 8
    det = Counted(max_epochs=2, patience=5).fit(x, y, groups=groups)
    assert (
        sum(seen) == 2 * module.WINDOWS_PER_EPOCH == 2 * det.fitted_choices()["windows_per_epoch"]
    )
    seen.clear()
    det.windows_per_epoch = None  # one pass: the README's plugin does not declare the parameter
    det.fit(x, y, groups=groups)
    assert sum(seen) == 2 * (200 - len(det.validation_y_))
    monkeypatch.setattr(module, "MAX_VALIDATION", 10)  # whole trials of 8 until 10 are held
    choices = Counted(max_epochs=1).fit(x, y, groups=groups).fitted_choices()
    assert choices["validation_windows"] == 16 and choices["validation_by"] == "trial"


@pytest.mark.slow  # four fits: 3 s on 2 busy cores
def test_the_engine_says_a_network_at_chance_did_not_learn_and_not_one_that_learned():
    from slipbench.engine.fitting import Job, TestSet, fit_and_test

    x, y = toy_windows(n=160, length=20, seed=2)
    groups = np.arange(160) // 8
    test = TestSet(x, y, groups)

    def fitted(labels):
        det = TinyCNN(max_epochs=3)
        det.windows_per_epoch = 256
        ((row, _),) = fit_and_test(Job(det, 0, 1000.0, x, labels, [test], train_groups=groups))
        return row

    learned = fitted(y)
    chance = fitted(np.random.default_rng(0).permutation(y))
    assert learned["validation_balanced_accuracy_lo"] > 0.5
    assert learned["train_balanced_accuracy_lo"] > 0.5
    assert "did not learn" not in learned["warnings"]
    assert chance["warnings"].startswith("did not learn: on its ")
    assert chance["validation_balanced_accuracy_lo"] <= 0.5
