"""Streaming metrics: how soon a detector notices slip, and how often it cries wolf.

Pure functions (numpy) over the scores a detector streams through test recordings
(:func:`slipbench.base.stream_scores`). Every index is a sample of the signal the detector
streams, and the labels lie on the same axis: for the paper's s_t = ||a_t|| - ||a_{t-1}||, one
sample shorter than its recording, sample i of s carries the label of raw sample i + 1.

Definitions, per recording:

- **labels**: int8 per sample, 1 slip, 0 no slip, -1 unlabelled (after a drop, say).
- **score k**: the probability of the window ending at sample ``ends[k]``; **decision k**:
  score k >= threshold.
- **alarm**: the first decision of a run of consecutive positive decisions, raised at sample
  ``ends[k]``. One run, however long, is one alarm; two runs are two.
- **onset**: a sample labelled 1 whose predecessor is labelled 0. A recording that starts in
  slip (sample 0 labelled 1) has its onset at sample 0: the labels give no earlier start, so the
  delay runs from the first sample, as for a detector switched on while the object already
  slips; such onsets are flagged ``at_start``. A 1 after an unlabelled sample is no onset: when
  that slip began is unknown.
- **delay** of an onset o: ``(a - o) / rate`` in ms, where a is the first alarm at or after o
  and before the next onset: the stream's own timing (samples and the rate), so a delay is
  the same on every machine. The time a detector takes to compute a score is no part of it:
  :mod:`slipbench.stream.cell` measures it apart and checks it against the hop period. An
  onset before the first score (inside the first window) is no exception: its delay includes
  the wait for the first full window. A run of positive decisions that began before the onset
  does not detect it: its alarm was raised while nothing slipped (a false alarm below), and the
  onset needs an alarm of its own.
- **detected**: an alarm with delay <= ``max_delay_ms``; **missed**: none; **censored**: the
  recording ends before o + max_delay_ms (and before the next onset), so a detector would not
  have its full time: whether an alarm came or not, a censored onset leaves the rates and the
  delays and is counted. The labels alone censor, so every detector's rates on the same
  streams are over the same onsets.
- **non-slip time**: the samples labelled 0 whose window (the sample and the ``window - 1``
  before it) holds no sample labelled 1, between the first and the last score: the time the
  detector watched nothing but non-slip. A **false alarm** is an alarm raised in non-slip time,
  so one before an onset while the labels are 0 is one. Alarms at other times (during slip, in
  unlabelled time, or just after a slip while the window still holds it) are neither
  detections nor false alarms.
- **false alarms per minute**: false alarms / minutes of non-slip time, pooled over the
  recordings of a scenario (or all).

Over many recordings: the detection rate is detected / (detected + missed); the median and 95th
percentile delay are over detected onsets (``np.quantile``, linear); intervals are 95 %
percentile bootstraps over trials (whole trials resampled, every onset and minute of a trial
kept together, since the fingers of one hand share a trial), each statistic resampling the
trials that contribute to it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pandas as pd

from slipbench.errors import UsageError
from slipbench.seeding import rng_for
from slipbench.store.columns import (
    DETECTION_RATE,
    FALSE_ALARMS,
    MEDIAN_DELAY,
    P95_DELAY,
    STREAMED,
    names,
)
from slipbench.vocabulary import MAX_DELAY_MS

LEVEL = 0.95
N_RESAMPLES = 999
N_THRESHOLDS = 201  # thresholds of a sweep: quantiles 0, 0.5 %, ..., 100 % of the scores
#: How delays are timed, part of every streaming cell's key: "stream" = the stream's samples at
#: its rate, no time measured on the machine (issue 20; earlier delays held the compute time per
#: hop, and their cells must not be served for these).
DELAY_CLOCK = "stream"
_EVALUATED = ("detected", "missed")  # the onsets the detection rate counts (censored ones leave)


def onsets(labels: np.ndarray) -> np.ndarray:
    """Slip onsets: (k,) int64 sample indices where a label 1 follows a 0, and 0 when the
    first sample is labelled 1. ``labels``: (n_samples,) int with -1 unlabelled."""
    labels = np.asarray(labels)
    starts = np.flatnonzero((labels[1:] == 1) & (labels[:-1] == 0)) + 1
    return np.r_[0, starts] if len(labels) and labels[0] == 1 else starts.astype(np.int64)


def nonslip(labels: np.ndarray, window: int) -> np.ndarray:
    """(n_samples,) bool: samples labelled 0 whose window (the sample and the ``window - 1``
    before it) holds no sample labelled 1."""
    labels = np.asarray(labels)
    slips = np.r_[0, np.cumsum(labels == 1)]
    t = np.arange(len(labels))
    return (labels == 0) & (slips[t + 1] == slips[np.maximum(t + 1 - window, 0)])


@dataclass(frozen=True)
class Streams:
    """Scored recordings, ready for the metrics at any threshold (built by :func:`collect`).

    Attributes
    ----------
    scores, ends : (N,) every recording's scores and their samples, one recording after another.
    recording : (N,) int64, the recording (its position in the lists given) of each score.
    first : (N,) bool, True at each recording's first score.
    quiet : (N,) bool, True where the score's sample is non-slip time.
    onset_sample, onset_recording : (K,) int64, each onset and its recording.
    onset_first, onset_last : (K,) int64, the scores (indices into ``scores``) that may detect
        each onset: from the first at or after it to the last within its horizon (first > last
        when none may).
    onset_short : (K,) bool, the recording ends before the onset's horizon.
    onset_at_start : (K,) bool, the onset is the recording's sample 0.
    rate : (R,) float, each recording's sampling rate (Hz).
    quiet_minutes : (R,) float, each recording's non-slip time.
    trial, scenario, recording_id : (R,) str per recording.
    window, max_delay_ms : as given to :func:`collect`.
    """

    scores: np.ndarray
    ends: np.ndarray
    recording: np.ndarray
    first: np.ndarray
    quiet: np.ndarray
    onset_sample: np.ndarray
    onset_recording: np.ndarray
    onset_first: np.ndarray
    onset_last: np.ndarray
    onset_short: np.ndarray
    onset_at_start: np.ndarray
    rate: np.ndarray
    quiet_minutes: np.ndarray
    trial: np.ndarray
    scenario: np.ndarray
    recording_id: np.ndarray
    window: int
    max_delay_ms: float


@dataclass(frozen=True)
class Recorded:
    """What :func:`collect` takes besides the scores and labels: the window, the recordings'
    rates, trials, scenarios and ids, and the longest delay that still detects an onset."""

    window: int
    sampling_rate: float | Sequence[float]
    trials: Sequence[str]
    scenarios: Sequence[str]
    recording_ids: Sequence[str] | None = None
    max_delay_ms: float = MAX_DELAY_MS


def collect(
    ends: Sequence[np.ndarray],
    scores: Sequence[np.ndarray],
    labels: Sequence[np.ndarray],
    **options,
) -> Streams:
    """Gather the scored test recordings of one cell.

    Parameters
    ----------
    ends, scores : per recording, (n_scores,) the samples and scores of
        :func:`~slipbench.base.stream_scores` (no score at all is allowed: a recording
        shorter than the window then adds only its censored onsets).
    labels : per recording, (n_samples,) int8 labels of the streamed signal's samples.
    window : samples per window (non-slip time starts ``window - 1`` samples after a slip).
    sampling_rate : Hz, one for all recordings or one each.
    trials, scenarios : per recording; trials are the bootstrap's clusters, scenarios group the
        false alarms.
    recording_ids : per recording, for the onset table (default: their positions).
    max_delay_ms : an alarm later than this after the onset misses it.

    All but the first three are keywords (:class:`Recorded`).
    """
    rec = Recorded(**options)
    window, sampling_rate, trials, scenarios = (
        rec.window,
        rec.sampling_rate,
        rec.trials,
        rec.scenarios,
    )
    recording_ids, max_delay_ms = rec.recording_ids, rec.max_delay_ms
    n_rec = len(labels)
    rates = np.broadcast_to(np.asarray(sampling_rate, float), (n_rec,))
    for name, seq in (
        ("ends", ends),
        ("scores", scores),
        ("trials", trials),
        ("scenarios", scenarios),
    ):
        if len(seq) != n_rec:
            raise UsageError(f"{name} gives {len(seq)} recordings, labels {n_rec}")
    if not (np.isfinite(max_delay_ms) and max_delay_ms > 0):
        raise UsageError(f"max_delay_ms must be > 0, got {max_delay_ms}")
    ids = np.array(
        [str(i) for i in range(n_rec)] if recording_ids is None else [str(r) for r in recording_ids]
    )
    parts: dict[str, list] = {
        k: []
        for k in (
            "scores",
            "ends",
            "recording",
            "first",
            "quiet",
            "o_sample",
            "o_rec",
            "o_first",
            "o_last",
            "o_short",
            "o_start",
        )
    }
    quiet_minutes = np.zeros(n_rec)
    offset = 0
    for r in range(n_rec):
        e, s, lab = (
            np.asarray(ends[r], np.int64),
            np.asarray(scores[r], float),
            np.asarray(labels[r]),
        )
        if e.shape != s.shape or e.ndim != 1:
            raise UsageError(
                f"recording {ids[r]}: ends {e.shape} and scores {s.shape} must be one score per end"
            )
        if len(e) and (e[0] < 0 or e[-1] >= len(lab) or np.any(np.diff(e) <= 0)):
            raise UsageError(
                f"recording {ids[r]}: score samples must rise within the {len(lab)} labelled samples"
            )
        quiet = nonslip(lab, window)
        if len(e):
            quiet_minutes[r] = quiet[e[0] : e[-1] + 1].sum() / rates[r] / 60.0
        o = onsets(lab)
        # the last sample an alarm may fall on: the horizon, and before the next onset
        horizon = int(np.floor(max_delay_ms * rates[r] / 1000.0 + 1e-9))
        limit = np.minimum(o + horizon, np.r_[o[1:] - 1, np.iinfo(np.int64).max])
        parts["scores"].append(s)
        parts["ends"].append(e)
        parts["recording"].append(np.full(len(e), r, np.int64))
        parts["first"].append(np.arange(len(e)) == 0)
        parts["quiet"].append(quiet[e])
        parts["o_sample"].append(o)
        parts["o_rec"].append(np.full(len(o), r, np.int64))
        parts["o_first"].append(offset + np.searchsorted(e, o, "left"))
        parts["o_last"].append(offset + np.searchsorted(e, limit, "right") - 1)
        parts["o_short"].append(limit > len(lab) - 1)
        parts["o_start"].append(o == 0)
        offset += len(e)
    cat = {k: np.concatenate(v) if v else np.empty(0) for k, v in parts.items()}
    return Streams(
        scores=cat["scores"].astype(float),
        ends=cat["ends"].astype(np.int64),
        recording=cat["recording"].astype(np.int64),
        first=cat["first"].astype(bool),
        quiet=cat["quiet"].astype(bool),
        onset_sample=cat["o_sample"].astype(np.int64),
        onset_recording=cat["o_rec"].astype(np.int64),
        onset_first=cat["o_first"].astype(np.int64),
        onset_last=cat["o_last"].astype(np.int64),
        onset_short=cat["o_short"].astype(bool),
        onset_at_start=cat["o_start"].astype(bool),
        rate=np.array(rates, float),
        quiet_minutes=quiet_minutes,
        trial=np.array([str(t) for t in trials]),
        scenario=np.array([str(s) for s in scenarios]),
        recording_id=ids,
        window=int(window),
        max_delay_ms=float(max_delay_ms),
    )


@dataclass(frozen=True)
class Outcome:
    """What the alarms at one threshold did (:func:`outcome`).

    Attributes
    ----------
    threshold : float.
    status : (K,) str per onset: "detected", "missed" or "censored".
    alarm : (K,) int64, the sample of the detecting alarm (-1 when none).
    delay_ms : (K,) float, NaN unless detected.
    false_alarms : (R,) int64 per recording.
    """

    threshold: float
    status: np.ndarray
    alarm: np.ndarray
    delay_ms: np.ndarray
    false_alarms: np.ndarray


def outcome(streams: Streams, threshold: float) -> Outcome:
    """Onsets detected, missed or censored, delays and false alarms at ``threshold``."""
    st = streams
    n = len(st.scores)
    positive = st.scores >= threshold
    alarm = positive & (st.first | ~np.r_[False, positive[:-1]])
    # for every score, the next alarm at or after it (n: none)
    following = (
        np.minimum.accumulate(np.where(alarm, np.arange(n), n)[::-1])[::-1]
        if n
        else np.empty(0, np.int64)
    )
    nxt = np.r_[following, n][np.minimum(st.onset_first, n)]
    # an onset the recording cuts short leaves the rates whatever the alarms did: counting
    # only those a detector caught would give each detector its own denominator
    detected = (nxt <= st.onset_last) & ~st.onset_short
    at = np.where(detected, nxt, 0)
    sample = np.where(detected, st.ends[at] if n else 0, -1)
    delay = np.where(
        detected,
        (sample - st.onset_sample) / st.rate[st.onset_recording] * 1000.0,
        np.nan,
    )
    status = np.where(detected, "detected", np.where(st.onset_short, "censored", "missed"))
    false_alarms = np.bincount(st.recording[alarm & st.quiet], minlength=len(st.rate)).astype(
        np.int64
    )
    return Outcome(float(threshold), status, sample.astype(np.int64), delay, false_alarms)


# ----------------------------------------------------------------------------- summaries
def _figures(streams: Streams, o: Outcome, recordings: np.ndarray) -> dict[str, float]:
    """Point figures over the given recordings (bool mask (R,))."""
    mine = recordings[streams.onset_recording]
    det, miss = mine & (o.status == "detected"), mine & (o.status == "missed")
    delays = o.delay_ms[det]
    minutes = streams.quiet_minutes[recordings].sum()
    false = int(o.false_alarms[recordings].sum())
    n_eval = int(det.sum() + miss.sum())
    p50, p95 = np.quantile(delays, [0.5, 0.95]) if len(delays) else (np.nan, np.nan)
    return {
        "n_onsets": n_eval,
        "n_detected": int(det.sum()),
        "n_missed": int(miss.sum()),
        "n_censored": int((mine & (o.status == "censored")).sum()),
        "n_at_start": int((mine & streams.onset_at_start).sum()),
        DETECTION_RATE.name: float(det.sum() / n_eval) if n_eval else np.nan,
        MEDIAN_DELAY.name: float(p50),
        P95_DELAY.name: float(p95),
        "false_alarms": false,
        "nonslip_minutes": float(minutes),
        FALSE_ALARMS.name: float(false / minutes) if minutes > 0 else np.nan,
    }


class Draws(NamedTuple):
    """How a bootstrap draws: its seed, its interval's level and its number of resamples."""

    seed: int
    level: float
    n_resamples: int


def _intervals(
    streams: Streams, o: Outcome, recordings: np.ndarray, draws: Draws
) -> dict[str, float]:
    """Percentile bootstrap intervals over trials; every statistic resamples the trials that
    contribute to it (onsets for the detection rate, detected onsets for the delays, non-slip
    time for false alarms), and one seed draws them all. Fewer than two such trials: NaN."""
    seed, level, n_resamples = draws
    rng = rng_for(seed, "stream-bootstrap")
    trial_codes, trial_of_rec = np.unique(streams.trial, return_inverse=True)
    n_trials = len(trial_codes)
    mine = recordings[streams.onset_recording]
    t_onset = trial_of_rec[streams.onset_recording]
    det, miss = mine & (o.status == "detected"), mine & (o.status == "missed")
    per = {  # per trial: counts that the ratio statistics sum
        "det": np.bincount(t_onset[det], minlength=n_trials),
        "eval": np.bincount(t_onset[det | miss], minlength=n_trials),
        "fa": np.bincount(
            trial_of_rec[recordings], weights=o.false_alarms[recordings], minlength=n_trials
        ),
        "min": np.bincount(
            trial_of_rec[recordings], weights=streams.quiet_minutes[recordings], minlength=n_trials
        ),
    }
    alpha = (1 - level) / 2
    out: dict[str, float] = {}

    def interval(name: str, stats: np.ndarray) -> None:
        stats = stats[np.isfinite(stats)]
        lo, hi = np.quantile(stats, [alpha, 1 - alpha]) if len(stats) else (np.nan, np.nan)
        out[f"{name}_lo"], out[f"{name}_hi"] = float(lo), float(hi)

    def weights(keep: np.ndarray) -> np.ndarray | None:
        k = int(keep.sum())
        return (
            rng.multinomial(k, np.full(k, 1 / k), size=n_resamples).astype(float)
            if k >= 2
            else None
        )

    def ratio(name: str, num: np.ndarray, den: np.ndarray) -> None:
        keep = den > 0
        w = weights(keep)
        if w is None:
            out[f"{name}_lo"] = out[f"{name}_hi"] = np.nan
            return
        with np.errstate(invalid="ignore", divide="ignore"):
            interval(name, (w @ num[keep]) / (w @ den[keep]))

    ratio(DETECTION_RATE.name, per["det"].astype(float), per["eval"].astype(float))
    ratio(FALSE_ALARMS.name, per["fa"], per["min"])
    # delays: the pooled quantiles of each resample of the trials with detected onsets
    has = per["det"] > 0
    w = weights(has)
    if w is None:
        for name in (MEDIAN_DELAY.name, P95_DELAY.name):
            out[f"{name}_lo"] = out[f"{name}_hi"] = np.nan
    else:
        order = np.argsort(o.delay_ms[det], kind="stable")
        delays = o.delay_ms[det][order]
        column = np.cumsum(has) - 1  # trial -> column of w
        owner = column[t_onset[det][order]]
        stats = repeated_quantiles(delays, w[:, owner].astype(np.int64), np.array([0.5, 0.95]))
        interval(MEDIAN_DELAY.name, stats[:, 0])
        interval(P95_DELAY.name, stats[:, 1])
    return out


def repeated_quantiles(values: np.ndarray, counts: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``np.quantile(np.repeat(values, counts[b]), q)`` for every row ``b`` of ``counts`` at
    once, bit for bit (numpy's default ``linear`` method and its interpolation), without
    building the repeated arrays: a Python loop over 999 resamples led a streaming cell.

    Parameters
    ----------
    values : (n,) float, sorted ascending, finite.
    counts : (B, n) int, every row with a positive total.
    q : (k,) float in [0, 1].

    Returns
    -------
    (B, k) float64.
    """
    cum = counts.cumsum(axis=1)
    total = cum[:, -1]
    virtual = (total - 1)[:, None] * q[None]
    prev = np.floor(virtual)
    nxt = prev + 1
    above = virtual >= (total - 1)[:, None]
    prev[above] = nxt[above] = -1  # numpy's last element: -1, gamma from it as numpy takes it
    gamma = virtual - prev
    # position j of a row's repeated array holds values[searchsorted(cum[b], j, "right")]:
    # the rows searched as one, each shifted past the last
    last = np.where(above, (total - 1)[:, None], 0)
    shift = np.arange(len(cum), dtype=np.int64)[:, None] * (int(total.max()) + 1)
    flat = (cum + shift).ravel()

    def at(pos: np.ndarray) -> np.ndarray:
        pos = np.where(above, last, pos).astype(np.int64)
        i = (
            np.searchsorted(flat, pos + shift, "right")
            - np.arange(len(cum))[:, None] * cum.shape[1]
        )
        return values[i]

    a, b = at(prev), at(nxt)
    diff = b - a
    out = a + diff * gamma
    np.subtract(b, diff * (1 - gamma), out=out, where=gamma >= 0.5)
    return out


def summarize(
    streams: Streams,
    threshold: float,
    seed: int = 0,
    level: float = LEVEL,
    n_resamples: int = N_RESAMPLES,
) -> dict[str, float]:
    """Every streaming figure of one cell at ``threshold``, with bootstrap intervals over trials.

    Returns
    -------
    dict: ``threshold``; counts ``n_onsets`` (detected + missed), ``n_detected``, ``n_missed``,
    ``n_censored``, ``n_at_start``, ``false_alarms``, ``nonslip_minutes``, ``n_trials`` (every
    trial streamed), ``n_onset_trials`` (trials holding a detected or missed onset: the
    clusters the detection rate's and the delays' intervals resample) and ``n_nonslip_trials``
    (trials with non-slip time: those of the false alarms' interval); and
    ``detection_rate``, ``median_delay_ms``, ``p95_delay_ms``, ``false_alarms_per_min``, each
    with ``_lo``/``_hi``. A figure without data (no onset, no non-slip time) is NaN.
    """
    o = outcome(streams, threshold)
    everything = np.ones(len(streams.rate), bool)
    return {
        "threshold": float(threshold),
        "n_trials": len(np.unique(streams.trial)),
        "n_onset_trials": len(
            np.unique(streams.trial[streams.onset_recording[np.isin(o.status, _EVALUATED)]])
        ),
        "n_nonslip_trials": len(np.unique(streams.trial[streams.quiet_minutes > 0])),
        **_figures(streams, o, everything),
        **_intervals(streams, o, everything, Draws(seed, level, n_resamples)),
    }


def false_alarms_by_scenario(
    streams: Streams,
    threshold: float,
    seed: int = 0,
    level: float = LEVEL,
    n_resamples: int = N_RESAMPLES,
) -> pd.DataFrame:
    """False alarms per minute of non-slip time in each scenario, with intervals over trials:
    one row per scenario (columns ``scenario``, ``false_alarms``, ``nonslip_minutes``,
    ``false_alarms_per_min`` and its ``_lo``/``_hi``)."""
    o = outcome(streams, threshold)
    rows = []
    for scenario in np.unique(streams.scenario):
        mask = streams.scenario == scenario
        fig, ci = (
            _figures(streams, o, mask),
            _intervals(streams, o, mask, Draws(seed, level, n_resamples)),
        )
        rows.append(
            {
                "scenario": scenario,
                "false_alarms": fig["false_alarms"],
                "nonslip_minutes": fig["nonslip_minutes"],
                FALSE_ALARMS.name: fig[FALSE_ALARMS.name],
                **{k: ci[k] for k in (f"{FALSE_ALARMS.name}_lo", f"{FALSE_ALARMS.name}_hi")},
            }
        )
    return pd.DataFrame(rows)


# ----------------------------------------------------------------------------- threshold sweep
def sweep(streams: Streams, thresholds: np.ndarray | None = None) -> pd.DataFrame:
    """The trade-off curve: per threshold, ``detection_rate``, ``median_delay_ms``,
    ``p95_delay_ms``, ``false_alarms_per_min`` (all scenarios pooled), ``n_detected`` and
    ``n_onsets``, without intervals.

    ``thresholds`` default: the distinct 0th, 0.5th, ..., 100th percentiles of the scores (each
    a score itself: numpy's "lower" method).
    """
    if thresholds is None:
        thresholds = (
            np.unique(np.quantile(streams.scores, np.linspace(0, 1, N_THRESHOLDS), method="lower"))
            if len(streams.scores)
            else np.empty(0)
        )
    everything = np.ones(len(streams.rate), bool)
    rows = []
    for threshold in np.asarray(thresholds, float):
        fig = _figures(streams, outcome(streams, threshold), everything)
        rows.append(
            {
                "threshold": threshold,
                **{k: fig[k] for k in (*names(STREAMED), "n_detected", "n_onsets")},
            }
        )
    return pd.DataFrame(
        rows,
        columns=["threshold", *names(STREAMED), "n_detected", "n_onsets"],
    )


def operating_point(curve: pd.DataFrame, false_alarms_per_min: float = 1.0) -> float:
    """The threshold of a :func:`sweep` that detects most within a false-alarm budget: among the
    thresholds with at most ``false_alarms_per_min``, the highest detection rate, then the
    shortest median delay, then the lowest threshold. NaN when none keeps the budget.

    Chosen on the streams swept: pick it on training recordings' streams and evaluate it on
    the test recordings (:func:`summarize`) for a figure that has not seen its test data.
    """
    ok = curve[curve[FALSE_ALARMS.name] <= false_alarms_per_min]
    if ok.empty:
        return float("nan")
    best = ok.sort_values(
        [DETECTION_RATE.name, MEDIAN_DELAY.name, "threshold"],
        ascending=[False, True, True],
        na_position="last",
        kind="stable",
    )
    return float(best["threshold"].iloc[0])
