"""Causal scoring of a live signal: :class:`Streamer` and its batch twin :func:`stream_scores`.

A robot's control loop feeds a fitted detector the univariate signal s_t as it arrives and gets
one score and one 0/1 decision per hop, each from the last ``window`` samples only. Scores fall on
the samples ``window - 1, window - 1 + hop, window - 1 + 2 hop, ...`` (indices counted from the
first sample pushed): the score at sample e is the detector's probability for the window
``s[e - window + 1 : e + 1]``, what ``predict_proba`` gives that window (to float32 rounding
where a detector's arithmetic depends on the batch: wavelet-svm's, by up to 3e-6).

``detector.streamer(hop)`` (``BaseDetector``) makes one; a detector may return a subclass of
:class:`Streamer` that overrides :meth:`Streamer._push` for speed (the LSTM does), and it must
give the same scores as ``predict_proba`` on the same windows.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from .errors import PluginError, UsageError

if TYPE_CHECKING:
    from .base import BaseDetector

# The default hop: 10 samples, 10 ms at 1 kHz. Scores at 100 Hz match the 100 Hz - 1 kHz loops of
# grasp controllers, the hop's quantization of a delay (at most 10 ms) is 5 % of the 200 ms
# budget, and a stream costs a tenth of a score per sample.
DEFAULT_HOP = 10

# windows scored by one predict_proba call at most: bounds memory when a whole recording is
# pushed at once (at window 200 a batch is 6.5 MB of float32). It costs no speed: holweg scored
# 192,000 windows of 50 in 0.055 s of CPU in batches of 8192, 0.081 s in one call.
MAX_BATCH = 8192


def check_hop(hop: Any, window: int) -> int:
    """``hop`` as an int in [1, window], or a UsageError naming both values."""
    if isinstance(hop, (bool, np.bool_)) or not isinstance(hop, (int, np.integer)):
        raise UsageError(f"hop must be a whole number of samples, got {hop!r}")
    if not 1 <= hop <= window:
        raise UsageError(f"hop must be between 1 and the window ({window} samples), got {hop}")
    return int(hop)


def check_threshold(threshold: Any) -> float:
    """``threshold`` as a float in [0, 1], or a UsageError."""
    try:
        value = float(threshold)
    except (TypeError, ValueError):
        raise UsageError(f"threshold must be a number in [0, 1], got {threshold!r}") from None
    if not 0.0 <= value <= 1.0:
        raise UsageError(f"threshold must be a number in [0, 1], got {threshold!r}")
    return value


class Streamer:
    """One causal stream through a fitted detector; see the module docstring.

    Attributes
    ----------
    window : int, samples per window (the detector's ``window_length_``).
    hop : int, samples between two scores, 1 <= hop <= window.
    threshold : float in [0, 1]; a decision is 1 where score >= threshold (``predict`` uses 0.5).
        May be set at any time.
    n_samples : int, samples pushed since the start (or the last :meth:`reset`).
    n_scores : int, scores given since then.
    """

    def __init__(self, detector: "BaseDetector", hop: int, threshold: float = 0.5):
        self.detector = detector
        self.window = int(detector.window_length_)
        self.hop = check_hop(hop, self.window)
        self.threshold = threshold
        self.reset()

    @property
    def threshold(self) -> float:
        return self._threshold

    @threshold.setter
    def threshold(self, value: float) -> None:
        self._threshold = check_threshold(value)

    def reset(self) -> None:
        """Forget every sample: the next one pushed is sample 0 of a new stream."""
        self.n_samples = 0
        self.n_scores = 0
        self._tail = np.empty(0, np.float32)  # the samples later windows still need

    def push(self, samples: Any) -> tuple[np.ndarray, np.ndarray]:
        """Feed new samples of the signal (a number or a 1-D array, any length, even 0).

        Returns
        -------
        scores : (n,) float64, one per window completed by these samples, in order.
        decisions : (n,) int8, 1 where score >= threshold.

        Raises UsageError for samples that are not finite numbers, naming the first bad one by
        its index in the stream; the stream is then left as it was. A detector that returns
        scores that are not probabilities raises DetectorOutputError, and the stream starts anew.
        """
        try:
            x = np.asarray(samples, dtype=np.float32)
        except (TypeError, ValueError) as exc:
            raise UsageError(f"samples must be numbers: {exc}") from None
        if x.ndim != 1:
            if x.ndim > 1:
                raise UsageError(f"samples must be a number or a 1-D array of the univariate signal, got shape {x.shape}")
            x = x.reshape(1)
        x = np.ascontiguousarray(x)
        if not _all_finite(x):
            i = int(np.argmin(np.isfinite(x)))
            raise UsageError(f"sample {self.n_samples + i} of the stream is {x[i]} (NaN or infinity)")
        last = self.n_samples + len(x) - 1  # the stream index of the last new sample
        end = self.window - 1 + self.n_scores * self.hop  # where the next score falls
        n = (last - end) // self.hop + 1 if last >= end else 0
        scores = self._push(x, n)
        if not n:
            scores, decisions = _NO_SCORES, _NO_DECISIONS
        else:
            if not _all_probabilities(scores, n):
                try:
                    scores = self.detector._checked_output(scores, n)  # converts, or raises saying what is wrong
                except PluginError:  # DetectorOutputError
                    self.reset()  # the state has moved past samples that n_samples does not count
                    raise
            decisions = (scores >= self._threshold).view(np.int8)
        self.n_samples += len(x)
        self.n_scores += n
        return scores, decisions

    def _push(self, x: np.ndarray, n: int) -> np.ndarray:
        """Scores of the ``n`` (maybe 0) windows that the checked float32 samples ``x`` complete.

        The default: the windows cut from the kept tail and ``x``, scored by the detector's
        ``_predict_proba`` (input already checked), up to MAX_BATCH windows per call. An override
        keeps its own state; ``self.n_samples`` and ``self.n_scores`` are updated after it returns.
        """
        data = np.concatenate([self._tail, x]) if len(self._tail) else x
        first = self.n_samples - len(self._tail)  # stream index of data[0]
        scores = np.empty(0)
        if n:
            start = self.n_scores * self.hop - first  # where the next window starts in data
            # the n windows from data[start], hop apart; they end inside data by the count of n
            # (as_strided: sliding_window_view's checks cost more than scoring one window)
            views = np.lib.stride_tricks.as_strided(data[start:], (n, self.window), (self.hop * data.itemsize, data.itemsize), writeable=False)
            scores = np.concatenate([self.detector._predict_proba(np.ascontiguousarray(views[i : i + MAX_BATCH]))
                                     for i in range(0, n, MAX_BATCH)])
        keep = (self.n_scores + n) * self.hop - first  # the first sample a later window needs
        self._tail = data[keep:].copy()
        return scores


# A control loop pushes a few samples at a time, where each numpy call costs a microsecond or
# more (the 2 µs a sample budget of the LSTM); plain Python is faster on a few numbers.
SMALL = 32
_NO_SCORES, _NO_DECISIONS = np.empty(0), np.empty(0, np.int8)
_NO_SCORES.flags.writeable = _NO_DECISIONS.flags.writeable = False  # shared by every push that completes no window


def _all_finite(x: np.ndarray) -> bool:
    return all(map(math.isfinite, x.tolist())) if len(x) <= SMALL else bool(np.isfinite(x).all())


def _all_probabilities(scores: Any, n: int) -> bool:
    """Whether ``scores`` is an (n,) float64 array of numbers in [0, 1] (NaN is not)."""
    if not (isinstance(scores, np.ndarray) and scores.dtype == np.float64 and scores.shape == (n,)):
        return False
    if n <= SMALL:
        return all(0.0 <= v <= 1.0 for v in scores.tolist())
    return bool(((scores >= 0.0) & (scores <= 1.0)).all())


def stream_scores(detector: "BaseDetector", signal: Any, hop: int) -> tuple[np.ndarray, np.ndarray]:
    """Every score a fresh stream gives over ``signal``: what pushing the whole signal into
    ``detector.streamer(hop)`` returns, with where each score falls.

    Parameters
    ----------
    detector : a fitted detector.
    signal : (n_samples,) the univariate signal of one recording.
    hop : samples between scores, 1 <= hop <= window.

    Returns
    -------
    ends : (n_scores,) int64, the index in ``signal`` of each window's last sample:
        ``window - 1 + k * hop``.
    scores : (n_scores,) float64.

    A signal shorter than the window gives no score; it is a UsageError naming both lengths, as
    a window longer than the recording is.
    """
    stream = detector.streamer(hop)
    signal = np.asarray(signal)
    if signal.ndim == 1 and len(signal) < stream.window:
        raise UsageError(f"the signal has {len(signal)} samples, fewer than the window ({stream.window} samples)")
    scores, _ = stream.push(signal)
    return stream.window - 1 + stream.hop * np.arange(len(scores), dtype=np.int64), scores


def push_costs(stream: Streamer, pieces: list[np.ndarray]) -> tuple[float, float]:
    """What feeding ``pieces`` one push each costs, robust to other processes on the machine.

    Every push is timed on its own (wall time); the pushes up to the first score (compilation,
    warm-up) are left out, and the median of the pushes that complete a score, and of those
    that only buffer, stands for every push of its kind (a push that waited for another
    process's turn on the core is an outlier, not a cost).

    Returns
    -------
    (µs per sample of the pieces, the median ms of a push that completes a score)
    """
    stream.reset()
    times, scored = np.empty(len(pieces)), np.zeros(len(pieces), bool)
    for i, piece in enumerate(pieces):
        t0 = time.perf_counter()
        scores, _ = stream.push(piece)
        times[i] = time.perf_counter() - t0
        scored[i] = len(scores) > 0
    counted = np.arange(len(pieces)) > np.argmax(scored)
    if not (scored & counted).any():
        raise UsageError(f"timing a stream needs pieces that complete at least two scores "
                         f"(window {stream.window}, hop {stream.hop}, {sum(map(len, pieces))} samples)")
    total = sum(np.median(times[kind]) * kind.sum() for kind in (scored & counted, ~scored & counted) if kind.any())
    return total / sum(len(p) for p, c in zip(pieces, counted) if c) * 1e6, float(np.median(times[scored & counted]) * 1e3)


def hop_latency(detector: "BaseDetector", signal: Any, hop: int) -> float:
    """The detector's compute time per hop, in ms: the median wall time of the pushes that
    complete a score when ``signal`` is fed one hop at a time, as a control loop would
    (:func:`push_costs`). The streaming protocol adds it to every delay."""
    x = np.asarray(signal, np.float32)
    return push_costs(detector.streamer(hop), [x[i : i + hop] for i in range(0, len(x), hop)])[1]
