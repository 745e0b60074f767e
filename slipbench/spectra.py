"""What detectors share: amplitude spectra, the separation of two empirical distributions, band
growing around a peak, and the logistic that turns a decision value into a probability. Public
engine API for plugins (the built-ins use it as any plugin would)."""

from __future__ import annotations

import numpy as np


def logistic(z: np.ndarray) -> np.ndarray:
    """1 / (1 + exp(-z)), without overflow warnings (``scipy.special.expit``): a decision value
    of 0 maps to 0.5."""
    from scipy.special import expit  # here: a plugin's import (a cached run) needs no scipy

    return expit(np.asarray(z, dtype=np.float64))


def grow_band(inside: np.ndarray, peak: int) -> tuple[int, int]:
    """The first and last index of the run of True in ``inside`` (bool, (n_bins,)) that holds
    ``peak``: a band grown from its peak bin while its neighbours qualify."""
    lo = hi = peak
    while lo > 0 and inside[lo - 1]:
        lo -= 1
    while hi < len(inside) - 1 and inside[hi + 1]:
        hi += 1
    return lo, hi


def amplitude_spectrum(x: np.ndarray, sampling_rate: float) -> tuple[np.ndarray, np.ndarray]:
    """Single-sided FFT amplitude spectrum of each row.

    Parameters
    ----------
    x : (n, length) signals.

    Returns
    -------
    freqs : (length // 2 + 1,) Hz.
    amp : (n, length // 2 + 1) amplitudes, in the signal's unit (a sine of amplitude A reads A).
    """
    length = x.shape[-1]
    amp = np.abs(np.fft.rfft(x, axis=-1)) / length
    # fold the negative frequencies in; DC and (for even lengths) Nyquist have no mirror
    amp[..., 1 : (length + 1) // 2] *= 2
    return np.fft.rfftfreq(length, 1.0 / sampling_rate), amp


def best_threshold(values: np.ndarray, y: np.ndarray) -> tuple[float, int, float]:
    """The threshold at the largest separation of the class-wise empirical CDFs.

    Returns ``(threshold, direction, separation)``: slip is called where
    ``direction * (value - threshold) > 0``; ``separation`` is the largest
    |F_nonslip(t) - F_slip(t)|, the two-sample Kolmogorov-Smirnov statistic. The threshold sits
    halfway between the separating value and the next one, so no training value lies on it.
    """
    slip = np.sort(values[y == 1])
    other = np.sort(values[y == 0])
    candidates = np.unique(values)
    f_slip = np.searchsorted(slip, candidates, side="right") / len(slip)
    f_other = np.searchsorted(other, candidates, side="right") / len(other)
    gap = f_other - f_slip
    best = int(np.argmax(np.abs(gap)))
    upper = candidates[min(best + 1, len(candidates) - 1)]
    threshold = (
        (candidates[best] + upper) / 2
        if upper > candidates[best]
        else candidates[best] * (1 + 1e-9) + 1e-12
    )
    return float(threshold), (1 if gap[best] >= 0 else -1), float(abs(gap[best]))
