"""MiniRocket (Dempster, Schmidt & Webb, "MiniRocket: a very fast (almost) deterministic
transform for time series classification", KDD 2021), beyond the paper: random convolutional
kernels' proportions of positive values, standardized, into a cross-validated ridge classifier.

Uses aeon's implementation, which is multivariate: on windows of channels each kernel sums the
convolutions of a random subset of 1 to 9 channels (drawn with the seed), as in MiniRocket's
multivariate variant. Windows shorter than MiniRocket's minimum of 9 samples are padded with
zeros at the start (the signal is a difference, so zero is "no change"; channels are
standardized by the engine, so zero is their training mean); the scores are a logistic of the
ridge decision function.

Default ``n_kernels=1000`` (the paper of MiniRocket uses 10,000): a default-dataset cell at
window 5 holds 40,000 training windows, and 10,000 features for each took 11 GB and many minutes
on the 2-core development machine. The ridge's cross-validation dominates the fit: on 3,840
windows of 50 samples it took 9.6 s with 2,000 features and 1.7 s with 1,000, so the whole
paper stays within minutes. For the same reason the ridge is fitted on at most ``max_windows``
training windows (10,000 by default, drawn with the seed).
"""

from __future__ import annotations

import numpy as np
from sklearn.linear_model import RidgeClassifierCV

from slipbench.base import BaseDetector
from slipbench.errors import UsageError
from slipbench.params import Interval
from slipbench.spectra import logistic

MIN_LENGTH = 9


def _pad(x: np.ndarray) -> np.ndarray:
    """Series (..., length) zero-padded at the start to MiniRocket's minimum length."""
    short = MIN_LENGTH - x.shape[-1]
    return x if short <= 0 else np.pad(x, ((0, 0),) * (x.ndim - 1) + ((short, 0),))


def _series(x: np.ndarray) -> np.ndarray:
    """Windows (n, length) or (n, length, channels) as aeon's padded float32 series
    (n, channels, length)."""
    series = x[:, None, :] if x.ndim == 2 else np.moveaxis(x, 2, 1)
    return np.ascontiguousarray(_pad(series), dtype=np.float32)


class MiniRocketDetector(BaseDetector):
    """MiniRocket features and a ridge classifier; ``n_kernels`` features (rounded by MiniRocket)."""

    inputs = ("univariate", "channels")
    check_params = {"n_kernels": 168}
    requires = ("aeon",)
    install_hint = "pip install 'slipbench[minirocket]'"
    _parameter_constraints = {
        "n_kernels": Interval(int, 84, 100_000),
        "max_dilations_per_kernel": Interval(int, 1, 128),
        "max_windows": Interval(int, 10, None),
    }

    def __init__(self, n_kernels=1_000, max_dilations_per_kernel=32, max_windows=10_000):
        self.n_kernels = n_kernels
        self.max_dilations_per_kernel = max_dilations_per_kernel
        self.max_windows = max_windows

    def _features(self, x: np.ndarray) -> np.ndarray:
        # aeon's own transform kernel; calling it directly keeps the fitted state plain arrays
        from aeon.transformations.collection.convolution_based._minirocket import (
            MiniRocket,
            _static_transform_multi,
            _static_transform_uni,
        )

        params = (
            self.num_channels_,
            self.channel_indices_,
            self.dilations_,
            self.features_per_dilation_,
            self.biases_,
        )
        series = _series(x)
        if series.shape[1] == 1:  # aeon's own choice: its univariate kernel is the faster
            features = _static_transform_uni(series[:, 0], params, MiniRocket._indices)
        else:
            features = _static_transform_multi(series, params, MiniRocket._indices)
        return (features - self.mean_) / self.std_

    def _fit(self, x, y, seed):
        try:
            from aeon.transformations.collection.convolution_based import MiniRocket
        except ImportError as exc:
            raise UsageError(
                "the minirocket detector needs aeon: pip install 'slipbench[minirocket]'"
            ) from exc

        if len(x) > self.max_windows:
            keep = np.sort(
                np.random.default_rng(seed).choice(len(x), self.max_windows, replace=False)
            )
            x, y = x[keep], y[keep]
        transform = MiniRocket(
            self.n_kernels, self.max_dilations_per_kernel, n_jobs=1, random_state=seed
        )
        transform.fit(_series(x))
        (
            self.num_channels_,
            self.channel_indices_,
            self.dilations_,
            self.features_per_dilation_,
            self.biases_,
        ) = transform.parameters
        self.mean_, self.std_ = np.zeros(1, np.float32), np.ones(1, np.float32)
        raw = self._features(x)
        self.mean_, self.std_ = raw.mean(axis=0), raw.std(axis=0) + 1e-8
        ridge = RidgeClassifierCV(alphas=np.logspace(-3, 3, 10)).fit(
            (raw - self.mean_) / self.std_, y
        )
        self.coef_, self.intercept_ = ridge.coef_.ravel(), float(ridge.intercept_[0])
        self.alpha_ = float(ridge.alpha_)

    def _predict_proba(self, x):
        z = self._features(x) @ self.coef_ + self.intercept_
        return logistic(z)
