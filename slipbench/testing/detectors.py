"""The conformance checks of a detector: parameters, fit and predict on toy windows of every
length, refusals, save and load, streaming, and each input kind it declares."""

from __future__ import annotations

import functools
import io
import tempfile
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from slipbench.base import INPUT_SHAPES, BaseDetector, NotFittedError, clone, stream_scores
from slipbench.errors import UsageError
from slipbench.seeding import rng_for
from slipbench.testing.data import CHANNELS, LENGTHS, assert_refused, toy


def check_params_protocol(detector: BaseDetector) -> None:
    """__init__ stores parameters as given; get_params/set_params/clone round-trip."""
    params = detector.get_params()
    twin = clone(detector)
    assert type(twin) is type(detector) and twin.get_params() == params, (
        "clone must keep every parameter"
    )
    assert not any(k.endswith("_") for k in vars(twin)), "a new detector must hold no fitted state"
    assert twin.set_params(**params) is twin and twin.get_params() == params, (
        "set_params(**get_params()) must be a no-op"
    )
    assert_refused(
        UsageError,
        "no parameter",
        lambda: twin.set_params(no_such_parameter=1),
        "set_params with an unknown name",
    )


def check_fit_predict(detector: BaseDetector, kind: str = "univariate") -> None:
    """Shapes, ranges and determinism for windows of 5 to 200 samples; parameters untouched by
    fit; windows of another length (or channel count) refused."""
    channels = CHANNELS if kind == "channels" else 0
    for length in LENGTHS:
        x, y = toy(kind, 120, length)
        before = detector.get_params()
        a = clone(detector)
        assert a.fit(x, y, sampling_rate=1000.0, seed=3) is a, "fit must return the detector"
        assert a.get_params() == before, f"fit must not change parameters (window {length})"
        assert a.window_length_ == length and a.sampling_rate_ == 1000.0
        assert a.n_channels_ == channels, (
            f"n_channels_ must be {channels} after fitting on {kind} windows, got {a.n_channels_}"
        )
        proba, pred = a.predict_proba(x[:37]), a.predict(x[:37])
        assert proba.shape == (37,) and pred.shape == (37,), (
            f"window {length}: one score per window, got {proba.shape}"
        )
        assert np.all((proba >= 0) & (proba <= 1)), f"window {length}: probabilities outside [0, 1]"
        assert set(np.unique(pred)) <= {0, 1}, f"window {length}: predictions must be 0 or 1"
        again = clone(detector).fit(x, y, sampling_rate=1000.0, seed=3).predict_proba(x[:37])
        assert np.array_equal(proba, again), (
            f"window {length}: two fits with one seed must give the same scores"
        )
        other = x[:, :-1] if length > 5 else np.concatenate([x, x], axis=1)
        assert_refused(
            UsageError,
            f"{length}",
            functools.partial(a.predict_proba, other),
            "predict on another window length",
        )
        if channels:
            assert_refused(
                UsageError,
                f"{channels} channels",
                functools.partial(a.predict_proba, x[:, :, :-1]),
                "predict on another number of channels",
            )


def check_refusals(detector: BaseDetector, kind: str = "univariate") -> None:
    """NaN input, single-class training data and predicting before fit are refused clearly."""
    x, y = toy(kind, 40, 20)
    bad = x.copy()
    bad[3, 7] = np.nan
    assert_refused(
        UsageError, "NaN", lambda: clone(detector).fit(bad, y), "fit on windows with NaN"
    )
    assert_refused(
        UsageError,
        "only class",
        lambda: clone(detector).fit(x, np.zeros_like(y)),
        "fit on one class",
    )
    assert_refused(
        NotFittedError, "not fitted", lambda: clone(detector).predict_proba(x), "predict before fit"
    )
    fitted = clone(detector).fit(x, y, seed=0)
    assert_refused(
        UsageError, "NaN", lambda: fitted.predict_proba(bad), "predict on windows with NaN"
    )


def check_save_load(detector: BaseDetector, kind: str = "univariate") -> None:
    """A fitted detector saves to a pickle-free file and loads back with the same scores."""
    x, y = toy(kind, 60, 50)
    fitted = clone(detector).fit(x, y, seed=1)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "detector.npz"
        fitted.save(path)
        with zipfile.ZipFile(path) as zf:  # every member must load without pickle
            for member in zf.namelist():
                np.lib.format.read_array(io.BytesIO(zf.read(member)), allow_pickle=False)
        for loader in (type(detector).load, BaseDetector.load):
            loaded = loader(path)
            assert (
                type(loaded).__name__ == type(detector).__name__
                and loaded.get_params() == fitted.get_params()
                and loaded.n_channels_ == fitted.n_channels_
            )
            assert np.array_equal(loaded.predict_proba(x), fitted.predict_proba(x)), (
                "a loaded detector must score as saved"
            )


def check_uses_input(detector: BaseDetector, kind: str = "univariate") -> None:
    """Scores depend on the windows: a detector that ignores its input scores every window alike."""
    x, y = toy(kind, 120, 50)
    scores = clone(detector).fit(x, y, seed=0).predict_proba(x)
    assert np.ptp(scores) > 0, "every window got the same score: the detector ignores its input"


def check_streaming(detector: BaseDetector, kind: str = "univariate") -> None:
    """A stream gives ``predict_proba``'s scores of the windows it completes, at hops 1, 7 and the
    window, whether the recording is pushed whole or in pieces of 0 to 40 samples."""
    window = 30
    x, y = toy(kind, 120, window)
    fitted = clone(detector).fit(x, y, sampling_rate=1000.0, seed=0)
    signal = toy(kind, 50, window, seed=1)[0].reshape(50 * window, *x.shape[2:])  # a recording
    cuts = np.cumsum(rng_for(0, "toy", "pieces").integers(0, 41, len(signal)))
    pieces = np.split(signal, cuts[cuts < len(signal)])
    for hop in (1, 7, window):
        ends, scores = stream_scores(fitted, signal, hop)
        assert np.array_equal(ends, np.arange(window - 1, len(signal), hop)), (
            f"hop {hop}: scores must fall on samples window - 1 + k hop"
        )
        windows = np.lib.stride_tricks.sliding_window_view(signal, window, axis=0)[
            ends - window + 1
        ]
        batch = fitted.predict_proba(np.moveaxis(windows, -1, 1))  # (n, window[, channels])
        np.testing.assert_allclose(
            scores, batch, rtol=0, atol=1e-6, err_msg=f"hop {hop}: stream vs predict_proba"
        )
        # pieces change the batches predict_proba sees: wavelet-svm's float32 features score a
        # window 2.6e-6 apart alone and in a batch
        stream = fitted.streamer(hop)
        pushed = np.concatenate([stream.push(piece)[0] for piece in pieces])
        np.testing.assert_allclose(
            pushed, scores, rtol=0, atol=1e-5, err_msg=f"hop {hop}: pieces vs one push"
        )


def check_input_kinds(detector: BaseDetector) -> None:
    """``inputs`` declares known kinds; windows of an undeclared kind are refused by a UsageError
    naming their shape, and a detector fitted on one kind refuses the other."""
    inputs = type(detector).inputs
    assert (
        isinstance(inputs, tuple)
        and inputs
        and set(inputs) <= set(INPUT_SHAPES)
        and len(set(inputs)) == len(inputs)
    ), f"inputs must be a tuple of distinct kinds among {tuple(INPUT_SHAPES)}, got {inputs!r}"
    for kind in (k for k in INPUT_SHAPES if k not in inputs):
        x, y = toy(kind, 40, 20)
        assert_refused(
            UsageError,
            str(x.shape),
            functools.partial(clone(detector).fit, x, y),
            f"fit on {kind!r} windows, which the detector does not declare",
        )
    if len(inputs) > 1:
        (x, y), (other, _) = toy(inputs[0], 40, 20), toy(inputs[1], 40, 20)
        fitted = clone(detector).fit(x, y, seed=0)
        assert_refused(
            UsageError,
            "fitted on",
            lambda: fitted.predict_proba(other),
            f"predict on {inputs[1]!r} windows after fitting on {inputs[0]!r} windows",
        )


def _fast(detector: BaseDetector) -> BaseDetector:
    return clone(detector).set_params(**type(detector).check_params)


# checks run once per detector; then those run once per input kind the detector declares
DETECTOR_CHECKS: list[Callable[[BaseDetector], None]] = [check_params_protocol, check_input_kinds]
KIND_CHECKS: list[Callable[..., None]] = [
    check_fit_predict,
    check_refusals,
    check_uses_input,
    check_save_load,
    check_streaming,
]


def detector_checks(detector: BaseDetector) -> list[tuple[str, Callable[[BaseDetector], None]]]:
    """Every check of ``detector`` as (name, check): ``check_params_protocol``, then the rest,
    those that fit once per declared input kind (``<check>-channels`` on windows of channels)."""
    checks: list[tuple[str, Callable[[BaseDetector], None]]] = [
        (c.__name__, c) for c in DETECTOR_CHECKS
    ]
    for kind in (k for k in type(detector).inputs if k in INPUT_SHAPES):  # others: input_kinds
        suffix = "" if kind == "univariate" else f"-{kind}"
        checks += [(c.__name__ + suffix, functools.partial(c, kind=kind)) for c in KIND_CHECKS]
    return checks


def check_detector(detector: BaseDetector) -> None:
    """Run every conformance check on ``detector`` (its class's ``check_params`` applied)."""
    assert isinstance(detector, BaseDetector), f"{type(detector).__name__} is not a BaseDetector"
    for _, check in detector_checks(detector):
        check(detector if check is check_params_protocol else _fast(detector))
