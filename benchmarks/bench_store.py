"""Cost of the results store's guarantees, each against a reference measured in the same run:

- ``put`` (atomic, fsynced, umask-following) against a plain ``pq.write_table`` of the same
  row and predictions to their final names;
- a no-op ``consolidate`` and ``read_results`` of a consolidated folder (one file read and one
  ``stat`` per cell) against reading ``results.parquet`` alone;
- ``read_results`` after a kill (no results.parquet: every cell file read);
- ``cell_key`` (canonical JSON) against the old ``json.dumps(default=str)``;
- ``code_identity(slipbench)``: the first call (reads every source file) and a cached one.

    python benchmarks/bench_store.py [--cells 1000] [--windows 2000]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import tempfile
import time
import timeit
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from slipbench.base import Part
from slipbench.store import keys
from slipbench.store.results import RESULTS_FILE, ResultsStore, cell_key, read_results


def row(i: int) -> dict:
    return {
        "key": f"{i:020x}",
        "protocol": "window-size",
        "detector": "holweg",
        "status": "ok",
        "reason": "",
        "sensor_type": "Nano17",
        "sensor_instance": "index",
        "window": 5 + i % 6,
        "seed": 0,
        "accuracy": 0.5 + (i % 97) / 200,
        "auroc": 0.5 + (i % 13) / 30,
        "train_s": 0.01 * i,
        "finished_at": "2024-06-11T10:00:00+00:00",
    }


def predictions(i: int, n: int) -> pd.DataFrame:
    rng = np.random.default_rng(i)
    return pd.DataFrame(
        {
            "recording_id": np.repeat(f"r{i}", n),
            "window_index": np.arange(n),
            "y_true": rng.integers(0, 2, n).astype(np.int8),
            "score": rng.random(n),
        }
    )


def best(fn, repeats: int = 5) -> float:
    """The fastest of ``repeats`` calls, in seconds (the least disturbed by other work)."""
    return min(timeit.repeat(fn, number=1, repeat=repeats))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=1000)
    parser.add_argument(
        "--windows", type=int, default=2000, help="test windows per cell (predictions rows)"
    )
    args = parser.parse_args()
    root = Path(tempfile.mkdtemp(prefix="bench_store."))
    try:
        preds = [predictions(i, args.windows) for i in range(50)]
        plain = root / "plain"
        (plain / "cells").mkdir(parents=True)
        (plain / "predictions").mkdir()
        t0 = time.perf_counter()
        for i in range(50):
            pq.write_table(
                pa.Table.from_pandas(preds[i], preserve_index=False),
                plain / "predictions" / f"{i}.parquet",
            )
            pq.write_table(pa.Table.from_pylist([row(i)]), plain / "cells" / f"{i}.parquet")
        ref_put = (time.perf_counter() - t0) / 50

        def puts(folder: Path) -> float:
            store = ResultsStore(folder)
            t0 = time.perf_counter()
            for i in range(50):
                store.put(row(i), preds[i])
            return (time.perf_counter() - t0) / 50

        with_preds = puts(root / "with")
        fsync, os.fsync = os.fsync, lambda fd: None
        try:
            without_fsync = puts(root / "nofsync")
        finally:
            os.fsync = fsync
        print(
            f"put of a row and {args.windows} predictions: {with_preds * 1e3:.1f} ms ({without_fsync * 1e3:.1f} ms "
            f"without its fsyncs); plain pq.write_table of both {ref_put * 1e3:.1f} ms "
            f"(ratio {with_preds / ref_put:.1f}x)"
        )
        store = ResultsStore(root / "store")
        t0 = time.perf_counter()
        for i in range(args.cells):
            store.put(row(i))
        print(f"put of a row alone: {(time.perf_counter() - t0) / args.cells * 1e3:.2f} ms")

        killed = best(lambda: read_results(store.folder), 2)
        t0 = time.perf_counter()
        store.consolidate()
        first = time.perf_counter() - t0
        noop = best(store.consolidate)
        whole = best(lambda: read_results(store.folder))
        ref = best(lambda: pq.read_table(store.folder / RESULTS_FILE).to_pandas())
        print(
            f"{args.cells} cells: read_results without results.parquet (after a kill) {killed * 1e3:.0f} ms; "
            f"first consolidate {first * 1e3:.0f} ms"
        )
        print(
            f"no-op consolidate {noop * 1e3:.1f} ms, read_results {whole * 1e3:.1f} ms; reading results.parquet "
            f"alone {ref * 1e3:.1f} ms (ratios {noop / ref:.1f}x, {whole / ref:.1f}x)"
        )

        fields = {
            "dataset": "0f3c" * 8,
            "detector": "lstm",
            "params": {"hidden": 64, "learning_rates": (1e-3, 1e-4)},
            "cell": {"sensor_type": "Nano17", "speed_mm_s": np.float64(25.0)},
            "train": Part((("Nano17", "index"),), "train", (("material", "!=", "PVC"),)),
            "seed": 0,
        }
        n = 20000
        new = best(lambda: [cell_key(fields) for _ in range(n)], 3) / n
        old = (
            best(
                lambda: [
                    hashlib.sha256(
                        json.dumps(fields, sort_keys=True, default=str).encode()
                    ).hexdigest()[:20]
                    for _ in range(n)
                ],
                3,
            )
            / n
        )
        print(
            f"cell_key {new * 1e6:.1f} us; json.dumps(default=str) {old * 1e6:.1f} us (ratio {new / old:.1f}x)"
        )

        import slipbench

        keys._unit_identity.cache_clear()
        t0 = time.perf_counter()
        keys.code_identity(slipbench)
        cold = time.perf_counter() - t0
        cached = best(lambda: [keys.code_identity(slipbench) for _ in range(10000)], 3) / 10000
        print(
            f"code_identity(slipbench): first call {cold * 1e3:.1f} ms ({len(keys._source_files('slipbench'))} files), "
            f"cached {cached * 1e6:.2f} us"
        )
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
