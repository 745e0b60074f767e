"""Streaming: the detector API (Streamer, stream_scores), the LSTM's stateful kernel, and the
metric definitions pinned on hand-made streams with known onsets and alarms."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.lib.stride_tricks import sliding_window_view

from slipbench.base import (
    BaseDetector,
    DetectorOutputError,
    NotFittedError,
    Streamer,
    stream_scores,
)
from slipbench.engine.registry import detectors
from slipbench.errors import UsageError
from slipbench.stream import metrics as S
from slipbench.testing import toy_channel_windows, toy_windows


def alarms(decisions) -> np.ndarray:
    """Alarms: (m,) int64 indices of the decisions that start a run of positive decisions."""
    d = np.asarray(decisions).astype(bool)
    return np.flatnonzero(d & ~np.r_[False, d[:-1]])


def onset_table(streams: S.Streams, threshold: float) -> pd.DataFrame:
    """One row per onset at ``threshold``: recording, trial, scenario, onset (sample), at_start,
    status, alarm (sample, -1 none), delay_ms."""
    o = S.outcome(streams, threshold)
    r = streams.onset_recording
    return pd.DataFrame(
        {
            "recording": streams.recording_id[r],
            "trial": streams.trial[r],
            "scenario": streams.scenario[r],
            "onset": streams.onset_sample,
            "at_start": streams.onset_at_start,
            "status": o.status,
            "alarm": o.alarm,
            "delay_ms": o.delay_ms,
        }
    )


class Energy(BaseDetector):
    """Mean absolute value against a training median: cheap, deterministic, input-dependent."""

    def _fit(self, x, y, seed):
        self.cut_ = float(np.median(np.abs(x).mean(axis=1)))

    def _predict_proba(self, x):
        return 1.0 / (1.0 + np.exp(-(np.abs(x).mean(axis=1) - self.cut_)))


def _signal(n=3000, seed=0):
    rng = np.random.default_rng(seed)
    burst = np.sin(2 * np.pi * 60 * np.arange(n) / 1000.0) * (np.arange(n) % 700 > 400) * 3
    return (rng.normal(size=n) * 1.3 + burst).astype(np.float32)


def _reference(detector, signal, ends):
    """predict_proba on the windows ending at ``ends``."""
    w = detector.window_length_
    return detector.predict_proba(sliding_window_view(signal, w)[ends - w + 1])


def _pushed(stream, signal, seed):
    """Scores of ``signal`` pushed in pieces of random length (0 to 40 samples)."""
    rng = np.random.default_rng(seed)
    out, i = [], 0
    while i < len(signal):
        k = int(rng.integers(0, 41))
        out.append(stream.push(signal[i : i + k])[0])
        i += k
    return np.concatenate(out)


# ----------------------------------------------------------------------------- the streaming API
# every registered detector streams predict_proba's scores on each input it declares: the
# conformance suite's check_streaming (tests/plugins/test_conformance.py)


@settings(max_examples=40, deadline=None)
@given(
    cuts=st.lists(st.integers(0, 400), max_size=12),
    hop=st.integers(1, 20),
    window=st.integers(5, 20),
)
def test_pieces_of_any_size_give_the_scores_of_one_push(cuts, hop, window):
    hop = min(hop, window)
    x, y = toy_windows(60, window)
    detector = Energy().fit(x, y)
    signal = _signal(400)
    ends, whole = stream_scores(detector, signal, hop)
    stream = detector.streamer(hop)
    pieces = [stream.push(part)[0] for part in np.split(signal, np.sort(cuts))]
    assert np.array_equal(np.concatenate(pieces), whole)
    assert stream.n_samples == 400 and stream.n_scores == len(whole) == len(ends)


def test_decisions_follow_the_threshold_which_may_change_mid_stream():
    x, y = toy_windows(100, 20)
    detector = Energy().fit(x, y)
    signal = _signal(400)
    _, scores = stream_scores(detector, signal, 5)
    cut = float(np.median(scores))
    stream = detector.streamer(5, threshold=cut)
    s1, d1 = stream.push(signal[:200])
    assert d1.dtype == np.int8 and np.array_equal(
        d1, (s1 >= cut).astype(np.int8)
    )  # >=: a score on the threshold alarms
    stream.threshold = 0.9
    s2, d2 = stream.push(signal[200:])
    assert np.array_equal(d2, (s2 >= 0.9).astype(np.int8))
    assert np.array_equal(np.r_[s1, s2], scores)


def test_one_sample_at_a_time_and_reset():
    x, y = toy_windows(100, 10)
    detector = Energy().fit(x, y)
    signal = _signal(60)
    stream = detector.streamer(3)
    got = [stream.push(float(v)) for v in signal]  # plain numbers are one sample each
    assert [len(s) for s, _ in got[:9]] == [0] * 9 and len(
        got[9][0]
    ) == 1  # the first score at sample window - 1
    scores = np.concatenate([s for s, _ in got])
    assert np.array_equal(scores, stream_scores(detector, signal, 3)[1])
    assert stream.push([])[0].shape == (0,)
    stream.reset()
    assert stream.n_samples == 0 and np.array_equal(stream.push(signal)[0], scores)


def test_bad_arguments_and_samples_are_refused_by_name():
    x, y = toy_windows(100, 20)
    detector = Energy().fit(x, y)
    for hop in (0, 21, 2.5, True):
        with pytest.raises(UsageError, match="hop"):
            detector.streamer(hop)
    with pytest.raises(UsageError, match=r"window \(20 samples\), got 21"):
        detector.streamer(21)
    for threshold in (-0.1, 1.5, "high"):
        with pytest.raises(UsageError, match="threshold"):
            detector.streamer(5, threshold=threshold)
    with pytest.raises(NotFittedError):
        Energy().streamer(5)
    stream = detector.streamer(5)
    stream.push(np.ones(30))
    bad = np.ones(10)
    bad[4] = np.nan
    with pytest.raises(UsageError, match="sample 34 of the stream"):
        stream.push(bad)
    with pytest.raises(UsageError, match="1-D"):
        stream.push(np.ones((2, 5)))
    with pytest.raises(UsageError, match="numbers"):
        stream.push(["a"])
    assert stream.n_samples == 30  # the refused pushes changed nothing
    with pytest.raises(UsageError, match="4 samples, fewer than the window \\(20"):
        stream_scores(detector, np.ones(4), 5)


class ChannelEnergy(Energy):
    """Energy over every channel of a window."""

    inputs = ("univariate", "channels")

    def _fit(self, x, y, seed):
        self.cut_ = float(np.median(np.abs(x).reshape(len(x), -1).mean(axis=1)))

    def _predict_proba(self, x):
        return 1.0 / (1.0 + np.exp(-(np.abs(x).reshape(len(x), -1).mean(axis=1) - self.cut_)))


def test_a_stream_of_channels_takes_samples_of_every_channel():
    x, y = toy_channel_windows(100, 20, channels=3)
    detector = ChannelEnergy().fit(x, y)
    signal = toy_channel_windows(20, 20, channels=3, seed=1)[0].reshape(400, 3)
    ends, scores = stream_scores(detector, signal, 5)
    windows = sliding_window_view(signal, 20, axis=0)[ends - 19].transpose(0, 2, 1)
    np.testing.assert_array_equal(scores, detector.predict_proba(windows))
    stream = detector.streamer(5)
    assert stream.n_channels == 3
    one_by_one = np.concatenate([stream.push(sample)[0] for sample in signal])  # (3,) each
    np.testing.assert_array_equal(one_by_one, scores)
    stream.reset()
    pieces = np.split(signal, [0, 7, 7, 19, 150, 151])  # (k, 3), k = 0 included
    np.testing.assert_array_equal(np.concatenate([stream.push(p)[0] for p in pieces]), scores)
    assert stream.n_samples == 400 and stream.push([])[0].shape == (0,)


def test_a_stream_of_channels_refuses_other_shapes_and_names_the_bad_channel():
    x, y = toy_channel_windows(100, 20, channels=3)
    detector = ChannelEnergy().fit(x, y)
    stream = detector.streamer(5)
    stream.push(np.ones((30, 3)))
    for wrong in (np.ones(4), np.ones((2, 4)), np.ones((2, 3, 1)), 1.0):
        with pytest.raises(UsageError, match=r"array \(k, 3\) or one sample \(3,\).* 3 channels"):
            stream.push(wrong)
    bad = np.ones((10, 3))
    bad[4, 2] = np.nan
    with pytest.raises(UsageError, match="sample 34 of the stream, channel 2, is nan"):
        stream.push(bad)
    assert stream.n_samples == 30  # the refused pushes changed nothing
    with pytest.raises(
        UsageError,
        match=r"fitted on 3 channels: the signal must be \(n_samples, 3\), got shape \(300,\)",
    ):
        stream_scores(detector, np.ones(300), 5)
    with pytest.raises(UsageError, match="4 samples, fewer than the window"):
        stream_scores(detector, np.ones((4, 3)), 5)
    univariate = ChannelEnergy().fit(x[:, :, 0], y).streamer(5)
    with pytest.raises(UsageError, match="1-D array of the univariate signal"):
        univariate.push(np.ones((4, 3)))


def test_hop_latency_of_a_stream_of_channels():
    from slipbench.base import hop_latency

    x, y = toy_channel_windows(100, 20, channels=3)
    detector = ChannelEnergy().fit(x, y)
    assert hop_latency(detector, np.ones((400, 3), np.float32), 5) > 0


def test_a_detector_with_bad_scores_fails_the_stream_and_it_starts_anew():
    class Broken(Energy):
        def _predict_proba(self, x):
            return np.full(len(x), 1.5)

    x, y = toy_windows(100, 10)
    stream = Broken().fit(x, y).streamer(2)
    stream.push(np.ones(9))
    with pytest.raises(DetectorOutputError, match="outside"):
        stream.push(np.ones(5))
    assert stream.n_samples == 0


def test_a_detector_may_bring_its_own_streamer():
    class Counting(Streamer):
        def _push(self, x, n):
            super()._push(x, n)
            return np.full(n, 0.25)

    class Custom(Energy):
        def _streamer(self, hop, threshold):
            return Counting(self, hop, threshold)

    x, y = toy_windows(100, 10)
    ends, scores = stream_scores(Custom().fit(x, y), _signal(100), 10)
    assert len(ends) == 10 and np.all(scores == 0.25)


# ----------------------------------------------------------------------------- the LSTM's stateful kernel
@pytest.mark.parametrize("hidden, window", [(20, 50), (7, 23)])
def test_lstm_streams_carry_window_states_and_equal_predict_proba(hidden, window):
    lstm = detectors.get("lstm")
    x, y = toy_windows(200, window)
    detector = lstm(hidden_size=hidden, max_epochs=1, device="cpu").fit(x, y, seed=0)
    signal = _signal(2000)
    for hop in sorted({1, 3, 10, window - 1, window}):
        stream = detector.streamer(hop)
        assert type(stream).__name__ == "LSTMStreamer" and stream._state.shape == (
            -(-window // hop),
            2,
            hidden,
        )
        ends, scores = stream_scores(detector, signal, hop)
        np.testing.assert_allclose(scores, _reference(detector, signal, ends), rtol=0, atol=1e-6)
        assert np.array_equal(
            _pushed(stream, signal, hop), scores
        )  # the same arithmetic whatever the pieces


def test_lstm_stream_differs_from_a_stream_that_keeps_state_across_windows():
    """The paper's model resets its state per window: a score must not depend on samples
    before its window (a kernel that leaked state would fail here)."""
    lstm = detectors.get("lstm")
    x, y = toy_windows(200, 20)
    detector = lstm(max_epochs=1, device="cpu").fit(x, y, seed=0)
    a, b = _signal(200, seed=1), _signal(200, seed=2)
    b[100:] = a[100:]  # the same last 100 samples after different histories
    ea, sa = stream_scores(detector, a, 4)
    _, sb = stream_scores(detector, b, 4)
    later = ea - 19 >= 100
    assert np.array_equal(sa[later], sb[later]) and not np.array_equal(sa[~later], sb[~later])


# ----------------------------------------------------------------------------- metric definitions
WINDOW, RATE = 5, 1000.0  # 1 sample = 1 ms


def _streams(recordings, max_delay_ms=10.0, trials=None, scenarios=None):
    """Hand-made streams: each recording is (labels, positive samples); one score per sample
    from window - 1 on (hop 1), 1 where the decision is positive."""
    ends, scores, labels = [], [], []
    for lab, positive in recordings:
        lab = np.asarray(lab, np.int8)
        e = np.arange(WINDOW - 1, len(lab))
        d = np.zeros(len(lab))
        d[list(positive)] = 1.0
        ends.append(e), scores.append(d[e]), labels.append(lab)
    n = len(recordings)
    return S.collect(
        ends,
        scores,
        labels,
        window=WINDOW,
        sampling_rate=RATE,
        max_delay_ms=max_delay_ms,
        trials=trials or [f"t{i}" for i in range(n)],
        scenarios=scenarios or ["hold-slip"] * n,
    )


def _labels(*runs):
    """Labels from (value, length) runs."""
    return np.concatenate([np.full(k, v, np.int8) for v, k in runs])


def test_onsets_alarms_and_nonslip_time_definitions():
    assert S.onsets([-1, 1, 1, 0, 0, 1, 1, 0, 1, -1, 1]).tolist() == [
        5,
        8,
    ]  # a 1 after -1: no onset
    assert S.onsets([1, 1, 0, 1]).tolist() == [0, 3]  # a recording that starts in slip: onset at 0
    assert S.onsets([0, 0, -1]).tolist() == [] and S.onsets([]).tolist() == []
    assert alarms([0, 1, 1, 0, 1, 0, 0, 1]).tolist() == [1, 4, 7]  # once per run
    assert alarms([1, 1]).tolist() == [0]
    quiet = S.nonslip([0, 0, 1, 1, 0, 0, 0, 0, 0, -1], window=3)
    assert quiet.tolist() == [
        1,
        1,
        0,
        0,
        0,
        0,
        1,
        1,
        1,
        0,
    ]  # slip still in the window: not non-slip time


def test_a_hold_slip_recording_false_alarm_before_onset_then_detection():
    lab = _labels((0, 30), (1, 40), (-1, 10))  # hold, slip at 30, drop at 70
    positive = [12, 13, 14]  # one run before the onset: one false alarm, not three
    positive += list(range(33, 51))  # the detection, 3 ms after the onset
    positive += [55, 56, 75]  # a second alarm during slip and one in unlabelled time: neither
    streams = _streams([(lab, positive)])
    table = onset_table(streams, 0.5)
    assert table[["onset", "status", "alarm", "delay_ms", "at_start"]].values.tolist() == [
        [30, "detected", 33, 3.0, False]
    ]
    s = S.summarize(streams, 0.5)
    assert (s["false_alarms"], s["n_onsets"], s["n_detected"], s["detection_rate"]) == (
        1,
        1,
        1,
        1.0,
    )
    assert s["nonslip_minutes"] == pytest.approx(
        26 / RATE / 60
    )  # samples 4..29: from the first score to the onset
    assert s["false_alarms_per_min"] == pytest.approx(1 / (26 / RATE / 60))
    assert s["median_delay_ms"] == s["p95_delay_ms"] == 3.0


def test_a_missed_onset_and_the_maximum_delay_boundary():
    lab = _labels((0, 20), (1, 60))
    assert onset_table(_streams([(lab, [30])]), 0.5)["status"].tolist() == [
        "detected"
    ]  # 10 ms: at the limit
    missed = onset_table(_streams([(lab, [31])]), 0.5)
    assert missed[["status", "alarm"]].values.tolist() == [["missed", -1]] and np.isnan(
        missed["delay_ms"][0]
    )
    assert S.summarize(_streams([(lab, [31])]), 0.5)["detection_rate"] == 0.0


def test_a_delay_is_counted_on_the_stream_alone():
    """No time measured on the machine enters a delay or the horizon: the delay is the samples
    from the onset to the alarm at the rate, and an alarm exactly max_delay_ms after the onset
    still detects it."""
    lab = _labels((0, 20), (1, 60))
    row = onset_table(_streams([(lab, [24])]), 0.5).iloc[0]
    assert row["status"] == "detected" and row["delay_ms"] == 4.0
    last = onset_table(_streams([(lab, [30])]), 0.5).iloc[0]
    assert last["status"] == "detected" and last["delay_ms"] == 10.0
    s = S.summarize(_streams([(lab, [24])]), 0.5)
    assert "compute_ms" not in s and s["median_delay_ms"] == 4.0
    with pytest.raises(TypeError):
        S.collect([], [], [], window=5, sampling_rate=RATE, trials=[], scenarios=[], compute_ms=1.0)


def test_onset_trials_count_the_trials_the_intervals_resample():
    """3 trials of 5 onsets each among 12 trials of pressing: 15 onsets, 15 trials, yet the
    detection rate and delays rest on 3 clusters, and the cell is low-n."""
    from slipbench.stats.metrics import stream_low_n

    slip = _labels(*[(v, 20) for _ in range(5) for v in (0, 1)])
    press = _labels((0, 100))
    recs = [(slip, [25, 65, 105]) for _ in range(3)] + [(press, []) for _ in range(12)]
    s = S.summarize(_streams(recs, trials=[f"t{i}" for i in range(15)]), 0.5)
    assert (s["n_trials"], s["n_onsets"], s["n_onset_trials"], s["n_nonslip_trials"]) == (
        15,
        15,
        3,
        15,
    )
    assert stream_low_n(s["n_onset_trials"], s["n_onsets"], s["n_nonslip_trials"])
    assert not stream_low_n(s["n_trials"], s["n_onsets"])  # what counting every trial said


def test_a_run_that_began_before_the_onset_does_not_detect_it():
    lab = _labels((0, 20), (1, 60))
    through = S.summarize(_streams([(lab, range(15, 40))]), 0.5)
    assert (through["false_alarms"], through["n_detected"], through["n_missed"]) == (1, 0, 1)
    again = _streams(
        [(lab, list(range(15, 22)) + [26])]
    )  # the run ends; a new alarm 6 ms after the onset
    assert onset_table(again, 0.5)["delay_ms"].tolist() == [6.0]


def test_an_onset_at_the_first_sample_and_one_inside_the_first_window():
    at_start = onset_table(_streams([(_labels((1, 30), (0, 30)), [4])]), 0.5).iloc[0]
    assert (
        at_start["onset"] == 0 and at_start["at_start"] and at_start["delay_ms"] == 4.0
    )  # waits for the first window
    inside = onset_table(_streams([(_labels((0, 2), (1, 40)), [4])]), 0.5).iloc[0]
    assert inside["onset"] == 2 and not inside["at_start"] and inside["delay_ms"] == 2.0
    s = S.summarize(_streams([(_labels((1, 30), (0, 30)), [4])]), 0.5)
    assert s["n_at_start"] == 1 and s["n_detected"] == 1


def test_a_recording_with_no_onset_gives_only_false_alarms():
    s = S.summarize(_streams([(_labels((0, 100)), [10, 11, 12, 40, 41])], scenarios=["press"]), 0.5)
    assert (
        (s["n_onsets"], s["false_alarms"]) == (0, 2)
        and np.isnan(s["detection_rate"])
        and np.isnan(s["median_delay_ms"])
    )
    assert s["nonslip_minutes"] == pytest.approx(96 / RATE / 60)


def test_censored_onsets_and_the_next_onset_bound():
    short = _streams(
        [(_labels((0, 95), (1, 5)), [])]
    )  # 4 ms of slip left in the recording, no alarm
    s = S.summarize(short, 0.5)
    assert (s["n_censored"], s["n_onsets"]) == (1, 0)
    # an alarm in the time left does not bring it back: the labels alone censor
    assert onset_table(_streams([(_labels((0, 95), (1, 5)), [97])]), 0.5)["status"].tolist() == [
        "censored"
    ]
    # onsets at 10 and 14 (slip 10-11, stick 12-13): an alarm at 15 detects the second only
    two = onset_table(_streams([(_labels((0, 10), (1, 2), (0, 2), (1, 30)), [15])]), 0.5)
    assert two[["onset", "status", "delay_ms"]].fillna(-1).values.tolist() == [
        [10, "missed", -1],
        [14, "detected", 1.0],
    ]


def test_every_detector_is_scored_on_the_same_onsets():
    """Two detectors on the same streams, one catching the onset the recording cuts short
    and one not: the same onsets in each rate's denominator (the streams' own), the short
    one censored for both."""
    lab = _labels((0, 20), (1, 30), (0, 45), (1, 5))  # onsets at 20 and at 95 (cut short)
    eager, late = (S.summarize(_streams([(lab, alarms_at)]), 0.5) for alarms_at in ([22, 97], [22]))
    for s in (eager, late):
        assert (s["n_onsets"], s["n_censored"], s["n_detected"]) == (1, 1, 1)
    assert eager["detection_rate"] == late["detection_rate"] == 1.0


def test_an_alarm_just_after_slip_is_neither_false_nor_a_detection():
    lab = _labels((0, 10), (1, 10), (0, 30))  # slip 10-19
    streams = _streams(
        [(lab, [22, 30])], max_delay_ms=5
    )  # 22: slip still in the window; 30: a false alarm
    s = S.summarize(streams, 0.5)
    assert (s["false_alarms"], s["n_missed"]) == (1, 1)


def test_false_alarms_by_scenario():
    streams = _streams(
        [(_labels((0, 64)), [10, 20]), (_labels((0, 64)), []), (_labels((0, 124)), [30])],
        scenarios=["press", "press", "free-space"],
    )
    table = S.false_alarms_by_scenario(streams, 0.5).set_index("scenario")
    assert table.loc["press", "false_alarms"] == 2 and table.loc["free-space", "false_alarms"] == 1
    assert table.loc["press", "false_alarms_per_min"] == pytest.approx(2 / (120 / RATE / 60))
    assert table.loc["free-space", "false_alarms_per_min"] == pytest.approx(1 / (120 / RATE / 60))


def test_intervals_resample_whole_trials():
    hit = (_labels((0, 20), (1, 20), (0, 20), (1, 20)), [23, 63])
    miss = (_labels((0, 20), (1, 20), (0, 20), (1, 20)), [])
    # trial a: every onset detected, in two recordings (fingers); trial b: every onset missed
    streams = _streams([hit, hit, miss, miss], trials=["a", "a", "b", "b"])
    s = S.summarize(streams, 0.5, seed=3)
    assert s["detection_rate"] == 0.5 and s["n_trials"] == 2
    # resampling trials gives all-a, a+b or all-b; resampling onsets would give a narrow interval
    assert (s["detection_rate_lo"], s["detection_rate_hi"]) == (0.0, 1.0)
    assert s == S.summarize(streams, 0.5, seed=3)  # deterministic for a seed
    one = S.summarize(_streams([hit, hit], trials=["a", "a"]), 0.5)
    assert np.isnan(one["detection_rate_lo"]) and np.isnan(
        one["median_delay_ms_lo"]
    )  # one trial: no interval


def test_delay_intervals_pool_each_resample_of_trials():
    lab = _labels((0, 20), (1, 20))
    recs = [(lab, [20 + d]) for d in (1, 2, 3, 8, 9)]
    s = S.summarize(_streams(recs, trials=list("abcde")), 0.5, seed=0, n_resamples=2000)
    assert s["median_delay_ms"] == 3.0 and s["p95_delay_ms"] == pytest.approx(8.8)
    assert 1.0 <= s["median_delay_ms_lo"] <= 3.0 <= s["median_delay_ms_hi"] <= 9.0
    assert s["p95_delay_ms_hi"] == 9.0  # resamples holding trial e reach its delay


def test_sweep_and_the_operating_point_at_a_false_alarm_budget():
    lab = _labels((0, 200), (1, 100))
    scores = np.zeros(300)
    scores[[50, 100, 150]] = 0.6  # noise that alarms below 0.7
    scores[205:230] = 0.8  # the slip, 5 ms after the onset
    e = np.arange(WINDOW - 1, 300)
    streams = S.collect(
        [e],
        [scores[e]],
        [lab],
        window=WINDOW,
        sampling_rate=RATE,
        trials=["t"],
        scenarios=["hold-slip"],
        max_delay_ms=10.0,
    )
    curve = S.sweep(streams)
    assert set(curve["threshold"]) == {0.0, 0.6, 0.8}  # the scores themselves
    at = curve.set_index("threshold")
    assert at.loc[0.6, "false_alarms_per_min"] == pytest.approx(3 / (196 / RATE / 60))
    assert at.loc[0.8, "false_alarms_per_min"] == 0 and at.loc[0.8, "detection_rate"] == 1.0
    assert (
        at.loc[0.0, "detection_rate"] == 0.0
    )  # one run from the first score: a false alarm, the onset missed
    assert S.operating_point(curve, 1.0) == 0.8
    assert np.isnan(S.operating_point(curve[curve["threshold"] < 0.7], 1.0))


def test_collect_refuses_inconsistent_input():
    lab = _labels((0, 20))
    with pytest.raises(UsageError, match="ends gives 2 recordings, labels 1"):
        S.collect(
            [np.arange(4, 20)] * 2,
            [np.zeros(16)],
            [lab],
            window=5,
            sampling_rate=RATE,
            trials=["a"],
            scenarios=["x"],
        )
    with pytest.raises(UsageError, match="recording r1: score samples must rise within the 20"):
        S.collect(
            [np.arange(4, 21)],
            [np.zeros(17)],
            [lab],
            window=5,
            sampling_rate=RATE,
            trials=["a"],
            scenarios=["x"],
            recording_ids=["r1"],
        )


def test_push_costs_and_hop_latency():
    from slipbench.base import hop_latency, push_costs

    x, y = toy_windows(100, 20)
    detector = Energy().fit(x, y)
    signal = _signal(400)
    per_sample_us, scored_ms = push_costs(
        detector.streamer(5), [signal[i : i + 5] for i in range(0, 400, 5)]
    )
    assert per_sample_us > 0 and scored_ms > 0
    assert hop_latency(detector, signal, 5) > 0
    with pytest.raises(UsageError, match="at least two scores"):
        hop_latency(detector, signal[:22], 5)


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_repeated_quantiles_are_numpys_of_each_repeated_array_to_the_bit(seed):
    rng = np.random.default_rng(seed)
    n, k = int(rng.integers(1, 40)), int(rng.integers(1, 9))
    values = np.sort(np.round(rng.gamma(2.0, 30.0, n), int(rng.integers(0, 3))))
    counts = rng.multinomial(k, np.full(k, 1 / k), size=50)[:, rng.integers(0, k, n)]
    counts = counts[counts.sum(axis=1) > 0].astype(np.int64)
    q = np.array([0.5, 0.95])
    got = S.repeated_quantiles(values, counts, q)
    want = np.array([np.quantile(np.repeat(values, c), q) for c in counts]).reshape(got.shape)
    assert got.tobytes() == want.tobytes()
