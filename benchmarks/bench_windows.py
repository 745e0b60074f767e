"""Windowing throughput: cut 8 million samples (one sensor unit at scale 1.0) into
non-overlapping windows, against a plain copy of the same buffer measured in the same run.

    python benchmarks/bench_windows.py
"""

from __future__ import annotations

import timeit

import numpy as np
import pandas as pd

from slipbench.data.signals import Signals, balance

N_SAMPLES = 8_000_000
RECORDING = 25_000  # a 25 s recording at 1 kHz


def best_of(fn, repeats: int = 5) -> float:
    """The fastest of ``repeats`` calls, in seconds (the least disturbed by other work)."""
    return min(timeit.repeat(fn, number=1, repeat=repeats))


def main() -> None:
    n_rec = N_SAMPLES // RECORDING
    rng = np.random.default_rng(0)
    rec = pd.DataFrame(
        {
            "recording_id": [f"r{i}" for i in range(n_rec)],
            "scenario": np.where(
                np.arange(n_rec) % 2 == 0,
                "slip",
                np.where(np.arange(n_rec) % 4 == 1, "press", "free-space"),
            ),
            "material": np.where(np.arange(n_rec) % 4 == 3, None, "PVC"),
            "speed_mm_s": np.where(np.arange(n_rec) % 4 == 1, np.nan, 25.0),
        }
    )
    signals = Signals(
        rng.standard_normal(N_SAMPLES).astype(np.float32), np.arange(n_rec + 1) * RECORDING, rec
    )
    copy = best_of(lambda: signals.buffer.copy())
    print(f"reference: copy of {N_SAMPLES / 1e6:.0f} M float32 samples: {copy * 1e3:.1f} ms")
    for window in (5, 50, 200):
        t = best_of(lambda w=window: signals.windows(w))
        print(
            f"windows of {window:3d}: {t * 1e3:7.1f} ms = {N_SAMPLES / t / 1e6:6.0f} M samples/s = {t / copy:5.1f} x the copy"
        )
    windows = signals.windows(50)
    t = best_of(lambda: balance(windows, np.random.default_rng(0)), repeats=3)
    print(f"balancing {len(windows)} windows: {t * 1e3:.1f} ms = {t / copy:.1f} x the copy")


if __name__ == "__main__":
    main()
