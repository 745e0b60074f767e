"""Streaming cost: each built-in detector's cost per incoming sample when a control loop feeds
it one hop at a time and one sample at a time, against its batch cost (predict_proba on every
window the stream scores, all at once), as ratios measured in the same run.

    python benchmarks/bench_streaming.py [--window 50] [--hop 10] [--samples 10000] [--seconds 1]

Everything runs on one thread (numba's and BLAS's pools limited to one; ``--threads`` to
change): a stream runs on one, so the ratios compare work, and on a shared machine a parallel
call waits for its slowest thread whenever another process holds a core. Batch costs are the
best of repeated calls (wall time). Streaming costs time each push on its own, the median of the
pushes of a kind (those that complete a score, those that only buffer) standing for all of that
kind (``slipbench.base.push_costs``); the median push that completes a score is also the
detector's compute time per hop (``hop_latency``), which the streaming protocol reports as
``compute_ms_per_hop`` against its real-time budget, the hop period (delays do not include it).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numba
import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from slipbench.base import DEFAULT_HOP, push_costs, stream_scores
from slipbench.engine.registry import detectors
from slipbench.testing import toy_windows


def best_wall(call: Callable[[], object], units: int, seconds: float) -> float:
    """Wall µs per unit of ``call``: the best of repeated calls over at least ``seconds``, after
    one warm-up call (compilation)."""
    call()
    best, spent = np.inf, 0.0
    while spent < seconds or best == np.inf:
        t0 = time.perf_counter()
        call()
        dt = time.perf_counter() - t0
        best, spent = min(best, dt), spent + dt
    return best / units * 1e6


def recording(n: int, window: int, seed: int) -> np.ndarray:
    """A recording-like signal: toy slip and non-slip windows one after another."""
    x, _ = toy_windows(-(-n // window), window, seed)
    return x.ravel()[:n]


def measure(
    name: str, window: int, hop: int, n: int, seconds: float, seed: int = 0
) -> dict[str, float]:
    detector = detectors.get(name)()
    x, y = toy_windows(3840, window, seed)  # a default-dataset cell at window 50
    detector.fit(x, y, sampling_rate=1000.0, seed=seed)
    signal = recording(n, window, seed + 1)
    windows = np.ascontiguousarray(np.lib.stride_tricks.sliding_window_view(signal, window)[::hop])
    stream = detector.streamer(hop)
    hop_us, latency_ms = min(
        push_costs(stream, [signal[i : i + hop] for i in range(0, n, hop)]) for _ in range(3)
    )
    sample_us, _ = min(push_costs(stream, [signal[i : i + 1] for i in range(n)]) for _ in range(3))
    row = {
        "detector": name,
        "window": window,
        "hop": hop,
        "batch_us": best_wall(lambda: detector.predict_proba(windows), n, seconds),
        "stream_scores_us": best_wall(lambda: stream_scores(detector, signal, hop), n, seconds),
        "hop_push_us": hop_us,
        "sample_push_us": sample_us,
        "hop_latency_ms": latency_ms,
    }
    row["hop_push_vs_batch"] = row["hop_push_us"] / row["batch_us"]
    row["sample_push_vs_batch"] = row["sample_push_us"] / row["batch_us"]
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--detector", action="append", help="a detector id (repeatable); default: every built-in"
    )
    parser.add_argument("--window", type=int, default=50)
    parser.add_argument("--hop", type=int, default=DEFAULT_HOP)
    parser.add_argument(
        "--samples", type=int, default=10_000, help="samples of the streamed recording"
    )
    parser.add_argument(
        "--seconds", type=float, default=1.0, help="least time spent on each batch figure"
    )
    parser.add_argument("--threads", type=int, default=1, help="threads of numba and BLAS")
    args = parser.parse_args()
    numba.set_num_threads(args.threads)
    threadpool_limits(args.threads)
    names = args.detector or [n for n in detectors.names() if detectors.status(n).state == "ok"]
    table = pd.DataFrame(
        [measure(n, args.window, args.hop, args.samples, args.seconds) for n in names]
    )
    print(
        f"µs per incoming sample (window {args.window}, hop {args.hop}, a {args.samples}-sample recording, "
        f"{args.threads} thread(s)); batch: predict_proba on the same windows at once"
    )
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3g}"))


if __name__ == "__main__":
    main()
