"""Detector costs: train µs per sample, inference µs per window and peak memory for every
detector, and the speed figures a detector declares itself (``BaseDetector.benchmark``), as
ratios against a reference timed in the same run (timings on a shared machine drift; ratios
taken minutes apart do not).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import pandas as pd

from slipbench.data.toy import toy_windows
from slipbench.engine.fitting import PeakMemory
from slipbench.engine.registry import detectors


def detector_costs(
    names: list[str],
    n_windows: int,
    length: int,
    seed: int = 0,
    echo: Callable[[str], None] | None = None,
) -> pd.DataFrame:
    """Fit each detector once with its defaults on ``n_windows`` toy windows of ``length``
    samples (3840 x 50 is a default-dataset cell at window 50) and predict as many; ``echo``
    hears which detector is being timed (some take minutes)."""
    x, y = toy_windows(n_windows, length, seed)
    rows = []
    for name in names:
        if echo:
            echo(f"timing {name} on {n_windows} windows of {length} samples ...")
        detector = detectors.get(name)()
        with PeakMemory() as mem:
            t0 = time.perf_counter()
            detector.fit(x, y, sampling_rate=1000.0, seed=seed)
            t1 = time.perf_counter()
            detector.predict_proba(x)
            t2 = time.perf_counter()
        rows.append(
            {
                "detector": name,
                "train_us_per_sample": (t1 - t0) / x.size * 1e6,
                "infer_us_per_window": (t2 - t1) / n_windows * 1e6,
                "peak_mem_mb": mem.mb,
                "train_s": t1 - t0,
            }
        )
    return pd.DataFrame(rows)


def detector_benchmarks(
    names: list[str], length: int, seconds: float, seed: int = 0
) -> dict[str, pd.DataFrame]:
    """Each detector's own speed figures (``BaseDetector.benchmark``), for those that have them."""
    tables = {}
    for name in names:
        table = detectors.get(name).benchmark(length, seconds, seed)
        if table is not None:
            tables[name] = table
    return tables
