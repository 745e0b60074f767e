"""Amplitude spectra and the separation of two empirical distributions (shared by the
spectral detectors and the spectral analysis)."""

from __future__ import annotations

import numpy as np


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
    threshold = (candidates[best] + upper) / 2 if upper > candidates[best] else candidates[best] * (1 + 1e-9) + 1e-12
    return float(threshold), (1 if gap[best] >= 0 else -1), float(abs(gap[best]))
