"""Deterministic cells for the store's fault tests, and a writer process to kill.

``python storegen.py FOLDER N EVERY PREFIX`` stores cells PREFIX00000 .. PREFIX{N-1} through
ResultsStore.put, skipping those already finished (a resume), consolidating every EVERY puts
(0: only at the end). It prints "ready" once its imports are done.
"""

from __future__ import annotations

import sys

import numpy as np
import pandas as pd


def cell_row(prefix: str, i: int) -> dict:
    return {
        "key": f"{prefix}{i:05d}",
        "protocol": "window-size",
        "detector": "holweg",
        "status": "ok",
        "reason": "",
        "window": 5 + i % 7,
        "seed": i % 3,
        "accuracy": 50 + i / 7,
        "cell": f'{{"window": {5 + i % 7}}}',
    }


def cell_predictions(i: int, n: int = 3000) -> pd.DataFrame:
    rng = np.random.default_rng(i)
    return pd.DataFrame(
        {
            "recording_id": np.repeat(f"rec{i}", n),
            "window_index": np.arange(n),
            "y_true": rng.integers(0, 2, n).astype(np.int8),
            "score": rng.random(n),
        }
    )


def main(folder: str, n: int, every: int, prefix: str) -> None:
    from slipbench.store.results import ResultsStore

    store = ResultsStore(folder)
    done = store.finished()
    print("ready", flush=True)
    for i in range(n):
        row = cell_row(prefix, i)
        if row["key"] in done:
            continue
        store.put(row, cell_predictions(i))
        if every and (i + 1) % every == 0:
            store.consolidate()
    store.consolidate()


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4])
