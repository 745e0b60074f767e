"""Band-pass energy threshold (after Su et al., "Force estimation and slip detection/classification
for grip control using a biomimetic tactile sensor", Humanoids 2015): a causal Butterworth
band-pass over each window, the log of the mean filtered energy, and a threshold placed where the
empirical CDFs of slip and non-slip energies separate most, as ``holweg`` does.

The band is clipped to 0.9 times the Nyquist frequency. Fallback for low sampling rates: when the
clipped band is empty (its low edge at or above the clipped top), the detector uses
[Nyquist / 4, 0.9 Nyquist] instead, and says so in ``band_hz_`` and ``band_fallback_``. Either
change is declared as an override of ``band`` (a warning of the row; reports show what ran).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import butter, sosfilt

from slipbench.base import BaseDetector
from slipbench.params import Band, Interval
from slipbench.spectra import best_threshold, logistic


def effective_band(
    band: tuple[float, float], sampling_rate: float
) -> tuple[tuple[float, float], bool]:
    """The band actually used at ``sampling_rate``, and whether the fallback applied."""
    nyquist = sampling_rate / 2
    low, high = float(band[0]), min(float(band[1]), 0.9 * nyquist)
    if low >= high:
        return (nyquist / 4, 0.9 * nyquist), True
    return (low, high), False


class BandPass(BaseDetector):
    """Log band-pass energy, thresholded. ``band``: (low_hz, high_hz); ``order``: Butterworth order
    (a band-pass of order n has 2n poles); a low edge of 0 gives a low-pass."""

    _parameter_constraints = {"band": Band(), "order": Interval(int, 1, 10)}

    def __init__(self, band=(50.0, 400.0), order=4):
        self.band = band
        self.order = order

    def _energy(self, x: np.ndarray) -> np.ndarray:
        filtered = sosfilt(
            self.sos_, x, axis=1
        )  # zero initial state: each window on its own, causal
        return np.log(np.mean(filtered**2, axis=1) + 1e-20)

    def _fit(self, x, y, seed):
        band = (50.0, 400.0) if self.band is None else self.band
        (low, high), self.band_fallback_ = effective_band(band, self.sampling_rate_)
        self.band_hz_ = (low, high)
        if low > 0:
            self.sos_ = butter(
                self.order, [low, high], btype="bandpass", fs=self.sampling_rate_, output="sos"
            )
        else:
            self.sos_ = butter(
                self.order, high, btype="lowpass", fs=self.sampling_rate_, output="sos"
            )
        energy = self._energy(x)
        self.threshold_, self.direction_, self.separation_ = best_threshold(energy, y)
        self.scale_ = (
            float(np.std(energy)) or 1.0
        )  # scores: logistic of the distance, 0.5 on the threshold

    def fitted_choices(self):
        return {
            "band_hz": list(self.band_hz_),
            "band_fallback": bool(self.band_fallback_),
            "threshold": self.threshold_,
            "separation": self.separation_,
        }

    def overrides(self):
        asked = (50.0, 400.0) if self.band is None else tuple(map(float, self.band))
        if tuple(self.band_hz_) == asked:
            return {}
        nyquist = self.sampling_rate_ / 2
        why = (
            f"above Nyquist {nyquist:.3g} Hz, replaced by [Nyquist / 4, 0.9 Nyquist]"
            if self.band_fallback_
            else f"its top clipped to 0.9 x Nyquist ({nyquist:.3g} Hz)"
        )
        return {"band": ([round(f, 3) for f in self.band_hz_], why)}

    def _predict_proba(self, x):
        z = self.direction_ * (self._energy(x) - self.threshold_) / self.scale_
        return logistic(z)
