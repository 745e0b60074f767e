"""The conformance suite for detectors: ``check_detector(detector)`` runs every check and raises
AssertionError naming the first that fails. A third-party plugin runs it in its own tests::

    from slipbench.testing import check_detector
    def test_my_detector():
        check_detector(MyDetector())

A detector class may declare ``check_params``: hyperparameters that make these checks fast (few
epochs, few kernels); they are applied to a clone, never to the detector passed in.
"""

from __future__ import annotations

import io
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from .base import BaseDetector, NotFittedError, clone
from .errors import UsageError

LENGTHS = (5, 50, 200)


def toy_windows(n: int, length: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Balanced windows: non-slip is low noise, slip adds a 60 Hz burst (at 1 kHz) and more noise."""
    rng = np.random.default_rng(seed)
    y = np.arange(n) % 2
    t = np.arange(length) / 1000.0
    x = rng.normal(0, 1, (n, length)) * np.where(y, 2.0, 1.0)[:, None]
    x += y[:, None] * 3 * np.sin(2 * np.pi * 60 * t + rng.uniform(0, 2 * np.pi, (n, 1)))
    return x.astype(np.float32), y


def _raises(kind: type[Exception], words: str, call, what: str) -> None:
    try:
        call()
    except kind as exc:
        assert words.lower() in str(exc).lower(), f"{what}: the error should mention {words!r}, got: {exc}"
        return
    except Exception as exc:  # noqa: BLE001 - the wrong kind of error is the failure reported
        raise AssertionError(f"{what}: expected {kind.__name__}, got {type(exc).__name__}: {exc}") from exc
    raise AssertionError(f"{what}: expected {kind.__name__}, nothing was raised")


def check_params_protocol(detector: BaseDetector) -> None:
    """__init__ stores parameters as given; get_params/set_params/clone round-trip."""
    params = detector.get_params()
    twin = clone(detector)
    assert type(twin) is type(detector) and twin.get_params() == params, "clone must keep every parameter"
    assert not any(k.endswith("_") for k in vars(twin)), "a new detector must hold no fitted state"
    assert twin.set_params(**params) is twin and twin.get_params() == params, "set_params(**get_params()) must be a no-op"
    _raises(UsageError, "no parameter", lambda: twin.set_params(no_such_parameter=1), "set_params with an unknown name")


def check_fit_predict(detector: BaseDetector) -> None:
    """Shapes, ranges and determinism for windows of 5 to 200 samples; parameters untouched by fit."""
    for length in LENGTHS:
        x, y = toy_windows(120, length)
        before = detector.get_params()
        a = clone(detector)
        assert a.fit(x, y, sampling_rate=1000.0, seed=3) is a, "fit must return the detector"
        assert a.get_params() == before, f"fit must not change parameters (window {length})"
        assert a.window_length_ == length and a.sampling_rate_ == 1000.0
        proba, pred = a.predict_proba(x[:37]), a.predict(x[:37])
        assert proba.shape == (37,) and pred.shape == (37,), f"window {length}: one score per window, got {proba.shape}"
        assert np.all((proba >= 0) & (proba <= 1)), f"window {length}: probabilities outside [0, 1]"
        assert set(np.unique(pred)) <= {0, 1}, f"window {length}: predictions must be 0 or 1"
        again = clone(detector).fit(x, y, sampling_rate=1000.0, seed=3).predict_proba(x[:37])
        assert np.array_equal(proba, again), f"window {length}: two fits with one seed must give the same scores"
        _raises(UsageError, f"{length}", lambda: a.predict_proba(x[:, :-1] if length > 5 else np.c_[x, x]), "predict on another window length")


def check_refusals(detector: BaseDetector) -> None:
    """NaN input, single-class training data and predicting before fit are refused clearly."""
    x, y = toy_windows(40, 20)
    bad = x.copy()
    bad[3, 7] = np.nan
    _raises(UsageError, "NaN", lambda: clone(detector).fit(bad, y), "fit on windows with NaN")
    _raises(UsageError, "only class", lambda: clone(detector).fit(x, np.zeros_like(y)), "fit on one class")
    _raises(NotFittedError, "not fitted", lambda: clone(detector).predict_proba(x), "predict before fit")
    fitted = clone(detector).fit(x, y, seed=0)
    _raises(UsageError, "NaN", lambda: fitted.predict_proba(bad), "predict on windows with NaN")


def check_save_load(detector: BaseDetector) -> None:
    """A fitted detector saves to a pickle-free file and loads back with the same scores."""
    x, y = toy_windows(60, 50)
    fitted = clone(detector).fit(x, y, seed=1)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "detector.npz"
        fitted.save(path)
        with zipfile.ZipFile(path) as zf:  # every member must load without pickle
            for member in zf.namelist():
                np.lib.format.read_array(io.BytesIO(zf.read(member)), allow_pickle=False)
        from .registry import detectors

        loaders = [type(detector).load] + ([BaseDetector.load] if detector.name in detectors.names() else [])
        for loader in loaders:
            loaded = loader(path)
            assert type(loaded).__name__ == type(detector).__name__ and loaded.get_params() == fitted.get_params()
            assert np.array_equal(loaded.predict_proba(x), fitted.predict_proba(x)), "a loaded detector must score as saved"


def check_detector(detector: BaseDetector) -> None:
    """Run every conformance check on ``detector`` (its class's ``check_params`` applied)."""
    assert isinstance(detector, BaseDetector), f"{type(detector).__name__} is not a BaseDetector"
    check_params_protocol(detector)
    fast = clone(detector).set_params(**getattr(type(detector), "check_params", {}))
    check_fit_predict(fast)
    check_refusals(fast)
    check_save_load(fast)
