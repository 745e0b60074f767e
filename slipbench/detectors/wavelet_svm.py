"""Wavelet features and an RBF support vector machine (after the DWT + SVM slip classifiers of,
e.g., Fernandez et al., "Micro-vibration-based slip detection in tactile force sensors", Sensors
2014): a discrete wavelet decomposition of each window (PyWavelets), per level the log energy,
log standard deviation, log mean and log largest absolute coefficient, standardized, into an SVM
with balanced class weights. On windows of channels the same features are computed for each
channel and concatenated (channel by channel), so the SVM sees every channel's spectrum; the RBF
width scales with the number of features, as on the univariate signal.

Speed: the RBF kernel is approximated with a Nystroem map (``n_components`` landmarks drawn from
the training windows, scikit-learn) and a linear SVM is trained on it, so training is linear in
the number of windows (80,000 windows take seconds, where an exact kernel SVM takes hours).
Short windows: the wavelet falls back to Haar when ``wavelet`` does not fit one level, and the
level is capped at the deepest useful one (``pywt.dwt_max_level``), so 5-sample windows work.
"""

from __future__ import annotations

import numpy as np
import pywt
from sklearn.kernel_approximation import Nystroem
from sklearn.svm import LinearSVC

from slipbench.base import BaseDetector
from slipbench.params import Interval, Options
from slipbench.spectra import logistic


def wavelet_and_level(length: int, wavelet: str, level: int) -> tuple[str, int]:
    """The wavelet and level used for windows of ``length`` samples."""
    if pywt.dwt_max_level(length, pywt.Wavelet(wavelet).dec_len) < 1:
        wavelet = "haar"
    return wavelet, max(1, min(level, pywt.dwt_max_level(length, pywt.Wavelet(wavelet).dec_len)))


class WaveletSVM(BaseDetector):
    """DWT statistics into an RBF SVM (Nystroem approximation), of the univariate signal or of
    each channel."""

    inputs = ("univariate", "channels")

    _parameter_constraints = {
        "wavelet": Options(tuple(pywt.wavelist(kind="discrete"))),
        "level": Interval(int, 1, 12),
        "C": Interval(float, 1e-6, None),
        "n_components": Interval(int, 10, 20_000),
    }

    def __init__(self, wavelet="db4", level=4, C=1.0, n_components=300):
        self.wavelet = wavelet
        self.level = level
        self.C = C
        self.n_components = n_components

    def _features(self, x: np.ndarray) -> np.ndarray:
        """Standardized log statistics per level: (n, features), or for windows of channels
        (n, window, C) each channel's features one after another, (n, C * features)."""
        coeffs = pywt.wavedec(x, self.wavelet_, level=self.level_, axis=1, mode="symmetric")
        feats = []
        for c in coeffs:  # (n, length) or (n, length, C)
            a = np.abs(c)
            feats += [np.mean(c**2, axis=1), np.std(c, axis=1), a.mean(axis=1), a.max(axis=1)]
        stats = np.stack(feats, axis=-1)  # (n, features) or (n, C, features)
        return (np.log(stats.reshape(len(x), -1) + 1e-12) - self.mean_) / self.std_

    def _fit(self, x, y, seed):
        self.wavelet_, self.level_ = wavelet_and_level(x.shape[1], self.wavelet, self.level)
        self.mean_, self.std_ = 0.0, 1.0
        raw = self._features(x)
        self.mean_, self.std_ = raw.mean(axis=0), raw.std(axis=0) + 1e-8
        feats = (raw - self.mean_) / self.std_
        nystroem = Nystroem(
            gamma=1.0 / feats.shape[1],
            n_components=min(self.n_components, len(x)),
            random_state=seed,
        )
        mapped = nystroem.fit_transform(feats)
        svm = LinearSVC(C=self.C, class_weight="balanced", random_state=seed).fit(mapped, y)
        # keep plain arrays only (safe to save): the landmarks, the map's normalization, the SVM
        self.landmarks_, self.normalization_ = nystroem.components_, nystroem.normalization_
        self.gamma_ = float(nystroem.gamma)
        self.coef_, self.intercept_ = svm.coef_.ravel(), float(svm.intercept_[0])

    def _predict_proba(self, x):
        f = self._features(x)
        d2 = (
            (f**2).sum(1)[:, None]
            - 2 * f @ self.landmarks_.T
            + (self.landmarks_**2).sum(1)[None, :]
        )
        mapped = np.exp(-self.gamma_ * np.maximum(d2, 0)) @ self.normalization_.T
        z = mapped @ self.coef_ + self.intercept_
        return logistic(z)
