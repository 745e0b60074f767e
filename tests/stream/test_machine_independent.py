"""Streaming figures that do not depend on the machine (issue 20): delays counted on the stream,
the compute time per hop as its own check against the hop period, low-n by the trials that hold
onsets. Compare and report on such rows: tests/stream/test_stream_protocol.py."""

from __future__ import annotations

import time

import numpy as np
import pandas as pd
import pytest
from toys import Energy

import slipbench.base
from slipbench.engine.fitting import Job, fit_and_test
from slipbench.stream.cell import Recordings, StreamTest, streamed_figures
from slipbench.testing import toy_windows

RATE, HOP = 1000.0, 5
MACHINE = {"compute_ms_per_hop", "realtime", "stream_s"}  # the fields a machine may change


def _recordings(n_slip: int, n_press: int, onsets_each: int = 1, seed: int = 0) -> Recordings:
    """``n_slip`` trials that hold, then slip (``onsets_each`` times, louder while slipping),
    and ``n_press`` trials of holding only; one recording per trial, 1 kHz."""
    rng = np.random.default_rng(seed)
    signals, labels, trials, scenarios = [], [], [], []
    for k in range(n_slip + n_press):
        # 100 samples after the last slip: its onset keeps its full 200 ms (else censored)
        lab = np.zeros(300 * max(onsets_each, 1) + 100, np.int8)
        if k < n_slip:
            for j in range(onsets_each):
                lab[300 * j + 150 : 300 * j + 250] = 1
        signals.append((rng.normal(0, 1, len(lab)) * np.where(lab == 1, 4.0, 1.0)).astype("f4"))
        labels.append(lab)
        trials.append(f"trial-{k}")
        scenarios.append("hold-slip" if k < n_slip else "press")
    return Recordings(signals, labels, trials, scenarios, list(trials), [RATE] * len(trials))


def _detector() -> Energy:
    x, y = toy_windows(200, 20)
    return Energy().fit(x, y)


def _same(a: dict, b: dict) -> list[str]:
    """The fields (other than what a machine may change) that differ between two results."""
    return [
        k for k in a if k not in MACHINE and not (a[k] == b[k] or (pd.isna(a[k]) and pd.isna(b[k])))
    ]


def test_a_slow_clock_changes_the_compute_check_not_the_delays(monkeypatch):
    test = StreamTest(_recordings(12, 12), _recordings(12, 12, seed=1), HOP, 200.0)
    detector = _detector()
    fast = streamed_figures(detector, 0, test)
    real = time.perf_counter
    # a machine 1000 times slower: every interval the clock measures is 1000 times longer
    monkeypatch.setattr(slipbench.base.time, "perf_counter", lambda: real() * 1000.0)
    slow = streamed_figures(detector, 0, test)
    monkeypatch.undo()
    assert fast["n_detected"] > 0 and np.isfinite(fast["median_delay_ms"])
    assert _same(fast, slow) == []
    for name in ("median_delay_ms", "p95_delay_ms", "op_median_delay_ms", "detection_rate"):
        assert fast[name] == slow[name] or (np.isnan(fast[name]) and np.isnan(slow[name])), name
    assert fast["tradeoff"] == slow["tradeoff"]
    # the compute check is where the machine shows
    assert fast["compute_budget_ms"] == slow["compute_budget_ms"] == HOP / RATE * 1000
    assert slow["compute_ms_per_hop"] > 100 * fast["compute_ms_per_hop"] > 0
    assert fast["realtime"] and not slow["realtime"]
    assert fast["compute_processor"] == slow["compute_processor"] != ""


@pytest.mark.parametrize(
    "n_slip, onsets_each, n_press, low",
    [
        (3, 4, 12, True),  # 3 test trials with onsets: 12 onsets, 15 test trials in all
        (3, 1, 2, True),  # 3 test trials with onsets, 5 in all
        (12, 1, 12, False),
    ],
)
def test_streaming_cells_are_low_n_by_the_trials_that_hold_onsets(
    n_slip, onsets_each, n_press, low
):
    x, y = toy_windows(200, 20)
    test = StreamTest(
        _recordings(n_slip, n_press, onsets_each), _recordings(4, 4, seed=1), HOP, 200.0
    )
    ((row, _),) = fit_and_test(Job(Energy(), 0, RATE, x, y, [test]))
    assert row["status"] == "ok", row["reason"]
    assert row["n_onset_trials"] == n_slip and row["n_test_trials"] == n_slip + n_press
    assert row["low_n"] is low
    # the report flags the same cells from the rows' counts
    from slipbench.report.tables import low_n

    assert low_n(pd.DataFrame([row])).iloc[0] == low


def test_report_rows_of_older_slipbench_are_low_n_by_their_test_trials():
    from slipbench.report.tables import low_n

    old = pd.DataFrame({"n_test_trials": [3, 30], "n_onsets": [40, 40], "status": "ok"})
    assert low_n(old).tolist() == [True, False]
