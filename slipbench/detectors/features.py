"""The reference baseline: summary statistics of each channel (or of the univariate signal) into
an L2-regularized logistic regression with balanced class weights (scikit-learn).

The statistics are the classic time-domain descriptors of vibration and EMG classifiers
(Hudgins, Parker & Scott, "A new strategy for multifunction myoelectric control", IEEE TBME
1993: mean absolute value, zero crossings, waveform length) with a level, a drift and an octave
spectrum. Each says something a slip detector might use:

- mean: the level (of channels standardized by the engine: the contact's load);
- slope (least squares): drift, as shear loads the contact before it slips;
- log standard deviation, log mean absolute difference (waveform length), log peak: how much,
  how fast and how impulsively the window moves (stick-slip snaps);
- zero-crossing rate: where, roughly, the energy lies in frequency;
- log mean power in ``n_bands`` octaves below Nyquist (the top band [Nyquist/2, Nyquist], then
  halves; the last one reaches down to the lowest bin above DC): the spectral content the paper's
  section IV finds in bands, whatever the sampling rate. Octaves with no bin (short windows) are
  dropped.

Logs are of spread-like values, floored at 1e-6 times the training windows' RMS so a constant
window stays finite whatever the unit. Everything is vectorized over windows and channels:
cost is an FFT and a few means per window, then one product with the coefficients.
"""

from __future__ import annotations

import numpy as np
from sklearn.linear_model import LogisticRegression
from sklearn.preprocessing import StandardScaler

from slipbench.base import BaseDetector
from slipbench.params import Interval
from slipbench.spectra import logistic

STATISTICS = ("mean", "slope", "log_std", "log_waveform_length", "log_peak", "zero_crossings")


def octave_matrix(length: int, n_bands: int) -> np.ndarray:
    """(length // 2 + 1, bands) weights that average an rfft power spectrum over octaves below
    Nyquist (columns: top octave first); DC has no weight and empty octaves no column."""
    bins = np.arange(length // 2 + 1)
    fraction = 2 * bins[1:] / length  # frequency / Nyquist, in (0, 1]
    band = np.minimum(np.floor(np.log2(1 / fraction)), n_bands - 1).astype(int)
    weights = np.zeros((len(bins), n_bands))
    weights[bins[1:], band] = 1.0
    weights = weights[:, weights.sum(axis=0) > 0]
    return weights / weights.sum(axis=0)


class Features(BaseDetector):
    """Per-channel summary statistics into a regularized logistic regression (the reference)."""

    inputs = ("univariate", "channels")
    reference = True
    _parameter_constraints = {
        "n_bands": Interval(int, 1, 12),
        "C": Interval(float, 1e-6, None),
        "max_iter": Interval(int, 10, None),
    }

    def __init__(self, n_bands=4, C=1.0, max_iter=1000):
        self.n_bands = n_bands
        self.C = C
        self.max_iter = max_iter

    def _statistics(self, x: np.ndarray) -> np.ndarray:
        """(n, features) for windows (n, length) or (n, length, C): each channel's statistics,
        channel after channel. Float64 throughout, so a window scores alike alone or in a batch."""
        # time last and contiguous, worked on in place: numpy reduces a (n, length, 6) array
        # over its middle axis several times slower, and temporaries cost as much as the sums
        centred = np.ascontiguousarray(np.moveaxis(x.reshape(*x.shape[:2], -1), 1, 2), np.float64)
        length, floor = centred.shape[-1], self.floor_
        mean = centred.mean(axis=-1)
        centred -= mean[..., None]
        t = np.arange(length) - (length - 1) / 2
        slope = centred @ (t / (t @ t))
        std = np.sqrt(np.einsum("nct,nct->nc", centred, centred) / length)
        steps = np.diff(centred, axis=-1)
        waveform = np.abs(steps, out=steps).mean(axis=-1)
        peak = np.maximum(centred.max(axis=-1), -centred.min(axis=-1))
        crossings = np.diff(np.signbit(centred), axis=-1).mean(axis=-1)
        spectrum = np.fft.rfft(centred, axis=-1)
        power = np.square(spectrum.real)
        power += np.square(spectrum.imag)
        bands = power @ (self.octaves_ / length)
        spread = np.log(np.stack([std, waveform, peak], axis=-1) + floor)
        stats = [mean[..., None], slope[..., None], spread, crossings[..., None]]
        both = np.concatenate([*stats, np.log(bands + floor**2)], axis=-1)
        return both.reshape(len(x), -1)  # (n, channels * statistics), channel after channel

    def _fit(self, x, y, seed):
        self.octaves_ = octave_matrix(x.shape[1], self.n_bands)
        self.floor_ = 1e-6 * (float(np.sqrt(np.mean(np.square(x, dtype=np.float64)))) or 1.0)
        scaler = StandardScaler()
        standard = scaler.fit_transform(self._statistics(x))
        model = LogisticRegression(
            C=self.C, class_weight="balanced", max_iter=self.max_iter, random_state=seed
        ).fit(standard, y)
        self.mean_, self.scale_ = scaler.mean_, scaler.scale_
        self.coef_, self.intercept_ = model.coef_.ravel(), float(model.intercept_[0])
        self.iterations_ = int(model.n_iter_[0])

    def fitted_choices(self):
        # lbfgs stops at max_iter without converging: a reader sees it rather than a warning
        return {"iterations": self.iterations_, "converged": self.iterations_ < self.max_iter}

    def _predict_proba(self, x):
        standard = (self._statistics(x) - self.mean_) / self.scale_
        return logistic(standard @ self.coef_ + self.intercept_)
