"""Holweg's FFT threshold (Holweg et al., "Slip detection by tactile sensors", 1996), as
Van Wyk & Falco apply it (section VI.A): the sum of FFT amplitudes over the most significant
frequency band, thresholded where the empirical CDFs of slip and non-slip sums separate most."""

from __future__ import annotations

import numpy as np

from slipbench.base import BaseDetector
from slipbench.errors import UsageError
from slipbench.params import Band, Interval
from slipbench.spectra import amplitude_spectrum, best_threshold, grow_band, logistic


def significant_band(freqs: np.ndarray, amp: np.ndarray, y: np.ndarray, keep: float) -> np.ndarray:
    """Bins of the most significant band: the contiguous run of bins around the bin whose
    slip and non-slip amplitudes differ most (two-sample KS statistic), extended while a bin's
    statistic stays at least ``keep`` times that maximum."""
    from scipy.stats import ks_2samp  # here: scipy.stats costs a second to import

    stat = ks_2samp(
        amp[y == 1], amp[y == 0], axis=0, method="asymp"
    ).statistic  # no exact p-values needed
    peak = int(np.argmax(stat))
    lo, hi = grow_band(stat >= keep * stat[peak], peak)
    return np.arange(lo, hi + 1)


class Holweg(BaseDetector):
    """FFT band-amplitude threshold.

    ``band``: (low_hz, high_hz), or None to choose the most significant band on the training
    windows (see :func:`significant_band`), the per-window counterpart of the paper's
    spectral analysis. ``keep``: how close to the peak separation a bin must be to join it.
    """

    _parameter_constraints = {"band": Band(), "keep": Interval(float, 0.0, 1.0)}

    def __init__(self, band=None, keep=0.8):
        self.band = band
        self.keep = keep

    def _sums(self, x: np.ndarray) -> np.ndarray:
        _, amp = amplitude_spectrum(x, self.sampling_rate_)
        return amp[:, self.bins_].sum(axis=1)

    def _fit(self, x, y, seed):
        freqs, amp = amplitude_spectrum(x, self.sampling_rate_)
        if self.band is None:
            self.bins_ = significant_band(freqs, amp, y, self.keep)
        else:
            lo, hi = (float(v) for v in self.band)
            # a bin counts when its frequency cell (centre +- half the resolution) meets the
            # band, so a band chosen at 1 Hz resolution still works for 5-sample windows
            half = freqs[1] / 2
            self.bins_ = np.flatnonzero((freqs + half > lo) & (freqs - half <= hi))
            if len(self.bins_) == 0:
                raise UsageError(
                    f"band {lo:g}-{hi:g} Hz holds no FFT bin of a {x.shape[1]}-sample window at "
                    f"{self.sampling_rate_:g} Hz (bins every {freqs[1]:g} Hz)"
                )
        self.band_hz_ = (float(freqs[self.bins_[0]]), float(freqs[self.bins_[-1]]))
        sums = amp[:, self.bins_].sum(axis=1)
        self.threshold_, self.direction_, self.separation_ = best_threshold(sums, y)
        # scores: a logistic of the log distance to the threshold, so 0.5 sits on it
        self.scale_ = float(np.std(np.log(sums + 1e-12))) or 1.0

    def fitted_choices(self):
        return {
            "band_hz": list(self.band_hz_),
            "threshold": self.threshold_,
            "separation": self.separation_,
        }

    def overrides(self):
        nyquist = self.sampling_rate_ / 2
        if self.band is None or float(self.band[1]) <= nyquist:
            return {}
        lo = float(self.band[0])
        return {"band": ([lo, nyquist], f"its top above Nyquist {nyquist:.3g} Hz, where bins end")}

    def _predict_proba(self, x):
        z = (
            self.direction_
            * (np.log(self._sums(x) + 1e-12) - np.log(self.threshold_ + 1e-12))
            / self.scale_
        )
        return logistic(z)
