"""Deterministic cells for the store's fault tests, and a writer process to kill; a store of
cells run under several seeds (:func:`repeats_store`).

``python storegen.py FOLDER N EVERY PREFIX`` stores cells PREFIX00000 .. PREFIX{N-1} through
ResultsStore.put, skipping those already finished (a resume), consolidating every EVERY puts
(0: only at the end). It prints "ready" once its imports are done.
"""

from __future__ import annotations

import json
import sys
import zlib

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
        "accuracy": 0.5 + i / 7000,
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


def repeats_store(
    folder, seeds=(0, 1, 2), seed_sd: float = 0.8, n_trials: int = 16, same_seeds: bool = False
) -> pd.DataFrame:
    """A results store of window-size cells (Nano17's index and middle fingers at windows 50
    and 200) run under ``seeds``, with predictions; returns its rows.

    Every seed tests the same ``n_trials`` slip and ``n_trials`` non-slip trials (10-30 windows
    each, both fingers recorded in each trial: ``trial`` is shared), as seeds of one run do. A
    window is called right with probability logistic(1.5 + trial effect + cell effect + seed
    effect): the trial effect N(0, 0.8^2) is the test noise, the seed effect N(0, ``seed_sd``^2)
    per cell and seed the retraining noise. ``same_seeds``: every seed gives seed 0's
    predictions (a detector that retraining does not move). Rows hold the figures of
    :func:`slipbench.stats.metrics.classification_figures` on the predictions.
    """
    from slipbench.stats.metrics import classification_figures
    from slipbench.store.results import ResultsStore

    store = ResultsStore(folder)
    rng = np.random.default_rng(7)
    trials = [f"t{i:02d}" for i in range(2 * n_trials)]
    y_trial = np.repeat([1, 0], n_trials)
    effect = dict(zip(trials, rng.normal(0, 0.8, len(trials))))
    length = dict(zip(trials, rng.integers(10, 31, len(trials))))
    rows = []
    for f, finger in enumerate(("index", "middle")):
        for window in (50, 200):
            cell = {"sensor_type": "Nano17", "sensor_instance": finger, "window": window}
            base = 1.5 + rng.normal(0, 0.3)
            for seed in seeds:
                draw = np.random.default_rng([7, seeds[0] if same_seeds else seed, window, f])
                shift = draw.normal(0, seed_sd)
                frames = []
                for trial, y in zip(trials, y_trial):
                    n = length[trial]
                    p = 1 / (1 + np.exp(-(base + effect[trial] + shift)))
                    right = draw.random(n) < p
                    u = 0.5 * draw.random(n)
                    score = np.where(right == bool(y), 0.5 + u, 0.5 - u)
                    frames.append(
                        pd.DataFrame(
                            {
                                "recording_id": f"{finger}-{trial}",
                                "window_index": np.arange(n),
                                "y_true": np.full(n, y, np.int8),
                                "score": score,
                                "trial": trial,
                            }
                        )
                    )
                pred = pd.concat(frames, ignore_index=True)
                figures = classification_figures(
                    pred["y_true"].to_numpy(),
                    pred["score"].to_numpy() >= 0.5,
                    pred["trial"].to_numpy(),
                    seed=0,
                    scores=pred["score"].to_numpy(),
                )
                text = json.dumps(cell, sort_keys=True)
                row = {
                    "key": f"{zlib.crc32(f'{text}|{seed}'.encode()):08x}",
                    "protocol": "window-size",
                    "detector": "holweg",
                    "split": "grouped",
                    "seed": seed,
                    **cell,
                    "cell": text,
                    "status": "ok",
                    "reason": "",
                    "dataset_fingerprint": "f00d",
                    **figures,
                }
                store.put(row, pred)
                rows.append(row)
    store.consolidate()
    return pd.DataFrame(rows)


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
