"""The worker's side of a streaming cell: stream whole recordings through a fitted model and
turn the scores into the cell's result fields (:mod:`slipbench.stream.metrics` defines them).

Plain data in (:class:`Recordings`, :class:`StreamTest`), plain fields out, so it runs in any
executor's process.
"""

from __future__ import annotations

import json
import platform
import time
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from slipbench.base import BaseDetector, hop_latency, stream_scores
from slipbench.store.columns import STREAMED as STREAMED_CELLS
from slipbench.store.columns import names
from slipbench.stream.metrics import (
    Streams,
    collect,
    false_alarms_by_scenario,
    operating_point,
    summarize,
    sweep,
)

OWN_THRESHOLD = 0.5  # the detector's own decision: predict() calls slip at a probability >= 0.5
BUDGET = 1.0  # false alarms per minute of the reported operating point (issue 10)
LATENCY_HOPS = (
    300  # pushes timed for the compute time per hop: a stable median, well under a second
)
#: the figures a streaming cell reports, as the results schema declares them
STREAMED = names(STREAMED_CELLS)
#: the sweep kept in a row: per threshold, the figures an operating point trades (the gate's)
CURVE = ("threshold", *names(STREAMED_CELLS, gated=True))


@dataclass
class Recordings:
    """Whole recordings to stream: per recording, its signal (n_r,) float32 (or its
    standardized channels, (n_r, n_channels)) and labels (n_r,) int8 (1 slip, 0 no slip, -1
    unlabelled), its trial, scenario, id and sampling rate (Hz)."""

    signals: list[np.ndarray]
    labels: list[np.ndarray]
    trials: list[str]
    scenarios: list[str]
    ids: list[str]
    rates: list[float]


@dataclass
class StreamTest:
    """What a streaming cell is tested on: the test recordings, the training recordings on
    which the operating point's threshold is chosen, the hop (samples) and the longest delay
    that still detects an onset (ms)."""

    test: Recordings
    train: Recordings
    hop: int
    max_delay_ms: float


def unknown_start(labels: np.ndarray) -> np.ndarray:
    """``labels`` with a leading run of slip (1) marked unlabelled (-1): a recording that starts
    in slip shows when the recording began, not when slip began, so the "onset at the first
    sample" of :mod:`slipbench.stream.metrics` would time the wait for the first full window (every
    detector the same) and swamp the onsets that were seen. Its later non-slip time still counts."""
    if not len(labels) or labels[0] != 1:
        return labels
    out = labels.copy()
    out[: int(np.argmax(labels != 1)) if (labels != 1).any() else len(labels)] = -1
    return out


def _streams(detector: BaseDetector, recs: Recordings, hop: int, max_delay_ms: float) -> Streams:
    window = int(detector.window_length_)
    ends, scores = [], []
    for signal in recs.signals:
        if len(signal) < window:  # no score at all: the recording adds only its censored onsets
            ends.append(np.empty(0, np.int64))
            scores.append(np.empty(0))
            continue
        e, s = stream_scores(detector, signal, hop)
        ends.append(e)
        scores.append(s)
    return collect(
        ends,
        scores,
        [unknown_start(lab) for lab in recs.labels],
        window=window,
        sampling_rate=recs.rates,
        trials=recs.trials,
        scenarios=recs.scenarios,
        recording_ids=recs.ids,
        max_delay_ms=max_delay_ms,
    )


def _compute_ms(detector: BaseDetector, recs: Recordings, hop: int) -> float:
    """The detector's compute time per hop (ms) on this machine: ``hop_latency`` over the first
    LATENCY_HOPS hops of the test signals laid end to end (where a piece crosses from one
    recording to the next does not change what a push costs)."""
    need = int(detector.window_length_) + LATENCY_HOPS * hop
    pieces, have = [], 0
    for signal in recs.signals:
        pieces.append(signal[: need - have])
        have += len(pieces[-1])
        if have >= need:
            break
    return hop_latency(detector, np.concatenate(pieces), hop)


@cache
def processor() -> str:
    """What the compute time was measured on: ``platform.processor()``; where that names only
    the architecture (Linux gives "x86_64" or nothing), the CPU's model name from
    /proc/cpuinfo; else ``platform.machine()``."""
    name = platform.processor()
    if name in ("", platform.machine()):
        try:
            for line in Path("/proc/cpuinfo").read_text().splitlines():
                if line.lower().startswith("model name") and ":" in line:
                    return " ".join(line.split(":", 1)[1].split())
        except OSError:
            pass
    return name or platform.machine() or "unknown"


def compute_check(detector: BaseDetector, recs: Recordings, hop: int) -> dict[str, Any]:
    """The compute time per hop against the real-time budget, as result fields.

    ``compute_ms_per_hop``: :func:`_compute_ms`, measured on ``compute_processor`` (this
    machine: the figure is this machine's, unlike every delay); ``compute_budget_ms``: the hop
    period, hop / rate (the strictest over the recordings' rates), the time a score may take
    before the next hop's samples are in; ``realtime``: the compute time is within it."""
    rates = [float(r) for r in recs.rates if np.isfinite(r) and r > 0]
    budget = hop / max(rates) * 1000.0 if rates else float("nan")
    compute_ms = _compute_ms(detector, recs, hop)
    return {
        "compute_ms_per_hop": compute_ms,
        "compute_budget_ms": budget,
        "realtime": bool(compute_ms <= budget),
        "compute_processor": processor(),
    }


def streamed_figures(detector: BaseDetector, seed: int, test: StreamTest) -> dict[str, Any]:
    """Every result field of a streaming cell for a fitted ``detector``. Recordings that start
    in slip give no onset (:func:`unknown_start`).

    At the detector's own threshold (0.5): ``detection_rate``, ``median_delay_ms``,
    ``p95_delay_ms``, ``false_alarms_per_min`` with ``_lo``/``_hi`` (bootstrap over test
    trials), the counts of :func:`slipbench.stream.metrics.summarize` and ``false_alarms_by_scenario``
    (JSON). At the operating point (at most 1 false alarm per minute, its threshold chosen by a
    sweep of the TRAINING recordings' streams and applied to the test streams): the same four
    figures prefixed ``op_``, and ``op_threshold`` (NaN with a note in ``op_note`` when no
    threshold keeps the budget on the training streams). Every delay is counted on the stream's
    samples alone, the same on any machine; the compute time per hop is its own check
    (:func:`compute_check`: ``compute_ms_per_hop``, ``compute_budget_ms``, ``realtime``,
    ``compute_processor``). ``tradeoff``: the sweep of the test streams (JSON list of
    points ``threshold``, ``detection_rate``, ``median_delay_ms``, ``false_alarms_per_min``),
    for the trade-off figure. ``stream_s``: wall time spent streaming.
    """
    t0 = time.perf_counter()
    streams = _streams(detector, test.test, test.hop, test.max_delay_ms)
    train = _streams(detector, test.train, test.hop, test.max_delay_ms)
    own = summarize(streams, OWN_THRESHOLD, seed)
    by_scenario = false_alarms_by_scenario(streams, OWN_THRESHOLD, seed)
    threshold = operating_point(sweep(train), BUDGET)
    note = ""
    if np.isnan(threshold):
        op = {k: np.nan for k in (*STREAMED, *(f"{f}_{b}" for f in STREAMED for b in ("lo", "hi")))}
        note = (
            f"no threshold keeps {BUDGET:g} false alarm per minute on the training streams"
            if len(train.scores)
            else "no training recording to choose the operating point on"
        )
    else:
        op = summarize(streams, threshold, seed)
    curve = sweep(streams)[list(CURVE)]
    stream_s = time.perf_counter() - t0
    return {
        **{k: v for k, v in own.items() if k != "threshold"},
        "threshold": OWN_THRESHOLD,
        "false_alarms_by_scenario": by_scenario.to_json(orient="records"),
        "op_threshold": float(threshold),
        "op_budget_per_min": BUDGET,
        "op_note": note,
        **{
            f"op_{k}": float(op[k])
            for k in (*STREAMED, *(f"{f}_{b}" for f in STREAMED for b in ("lo", "hi")))
        },
        "tradeoff": json.dumps(
            [
                {k: (None if not np.isfinite(v) else float(v)) for k, v in point.items()}
                for point in curve.to_dict("records")
            ]
        ),
        **compute_check(detector, test.test, test.hop),
        "n_test_recordings": len(test.test.signals),
        "n_train_recordings": len(test.train.signals),
        "stream_s": stream_s,
    }
