"""Cost of the results store's guarantees, each against a reference measured in the same run:

- ``put`` (atomic, fsynced, umask-following) against a plain ``pq.write_table`` of the same
  row and predictions to their final names;
- a no-op ``consolidate`` and ``read_results`` of a consolidated folder (one file read, proved
  whole by its table digest, and one ``stat`` per cell) and of its results.parquet alone,
  against reading ``results.parquet`` alone with pyarrow and pandas, for narrow rows (13
  columns) and rows as wide as a windowed cell's (about 100); the table digest's share, and
  each row's digest (the check a read made before, and makes on a file of an older slipbench);
- ``read_results`` after a kill (no results.parquet: every cell file read);
- ``cell_key`` (canonical JSON) against the old ``json.dumps(default=str)``;
- ``code_identity(slipbench)``: the first call (reads every source file) and a cached one.

    python benchmarks/bench_store.py [--cells 1000] [--windows 2000]

Output of a run: ``benchmarks/results/store.txt``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import shutil
import tempfile
import time
import timeit
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from slipbench.protocol import Part
from slipbench.store import columns, keys
from slipbench.store.digests import TABLE, proved_whole
from slipbench.store.results import RESULTS_FILE, ResultsStore, cell_key, read_results, row_digest


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


def wide_row(i: int) -> dict:
    """A windowed cell's row as the engine writes it: every column of the results schema but
    the streaming ones (about 90), so that what a read costs per value shows."""
    streaming = {c.name for c in (*columns.STREAM, *columns.GROUPS["Figures of a streaming cell"])}
    value = {"string": "Nano17-index", "int64": 1 + i % 5, "float64": 0.5 + i / 1e6, "bool": False}
    out = {c.name: value[c.type] for c in columns.COLUMNS.values() if c.name not in streaming}
    return out | {"key": f"{i:020x}", "cell": f'{{"window": {5 + i % 6}}}', "status": "ok"}


def folder_costs(store: ResultsStore, make, cells: int) -> None:
    """What a results folder of ``cells`` rows from ``make`` costs to write and read, against
    reading its results.parquet alone; with the share of the rows' digests, checked on every read."""
    t0 = time.perf_counter()
    for i in range(cells):
        store.put(make(i))
    put = (time.perf_counter() - t0) / cells
    killed = best(lambda: read_results(store.folder), 2)
    t0 = time.perf_counter()
    store.consolidate()
    first = time.perf_counter() - t0
    noop = best(lambda: ResultsStore(store.folder).consolidate())  # as a new command pays it
    again = best(store.consolidate)  # a run's later looks: what it proved is not proved again
    path = store.folder / RESULTS_FILE
    # taken in turns, so that a quiet moment favours neither (this machine is shared)
    ref, whole, alone = interleaved(
        [
            lambda: pq.read_table(path).to_pandas(),
            lambda: read_results(store.folder),
            lambda: read_results(path),
        ]
    )
    table = pq.read_table(path)
    assert proved_whole(table), "results.parquet is not proved whole by its table digest"
    digest = best(lambda: proved_whole(table))
    rows = table.to_pylist()
    digests = best(lambda: [row_digest(r) for r in rows])
    # as an older slipbench wrote it: row digests, no table digest (a folder without cells/)
    old = store.folder.parent / f"{store.folder.name}-older" / RESULTS_FILE
    old.parent.mkdir()
    metadata = {k: v for k, v in table.schema.metadata.items() if k != TABLE}
    pq.write_table(table.replace_schema_metadata(metadata), old)
    older = best(lambda: read_results(old), 3)
    print(
        f"{cells} cells of {len(make(0))} columns: put {put * 1e3:.2f} ms each; read_results "
        f"without results.parquet (after a kill) {killed * 1e3:.0f} ms; first consolidate "
        f"{first * 1e3:.0f} ms"
    )
    print(
        f"  no-op consolidate {noop * 1e3:.1f} ms ({again * 1e3:.1f} ms again in one run), "
        f"read_results {whole * 1e3:.1f} ms (the folder), {alone * 1e3:.1f} ms (its "
        f"results.parquet); reading results.parquet alone {ref * 1e3:.1f} ms (ratios "
        f"{noop / ref:.1f}x, {again / ref:.1f}x, {whole / ref:.1f}x, {alone / ref:.1f}x)"
    )
    print(
        f"  every digest checked: the table digest {digest * 1e3:.1f} ms ({digest / ref:.2f}x); "
        f"each row's digest, as a read checked them before {digests * 1e3:.1f} ms "
        f"({digests / ref:.1f}x), as it still does a file of an older slipbench: read_results "
        f"of one {older * 1e3:.1f} ms ({older / ref:.1f}x)"
    )


def interleaved(fns, repeats: int = 15) -> list[float]:
    """The fastest of ``repeats`` calls of each of ``fns``, called in turns, in seconds."""
    times = [[] for _ in fns]
    for _ in range(repeats):
        for fn, took in zip(fns, times):
            t0 = time.perf_counter()
            fn()
            took.append(time.perf_counter() - t0)
    return [min(took) for took in times]


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
    print(f"# {machine()}")
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
        for kind, make in (("narrow", row), ("wide", wide_row)):
            folder_costs(ResultsStore(root / kind), make, args.cells)

        wide = wide_row(0)
        fast = best(lambda: [keys.canonical(wide) for _ in range(2000)], 3) / 2000
        recursing = (
            best(
                lambda: [
                    {k: keys.canonical(v, f"key.{k}") for k, v in wide.items()} for _ in range(2000)
                ],
                3,
            )
            / 2000
        )
        print(
            f"canonical form of a {len(wide)}-column row: {fast * 1e6:.1f} us; each value through "
            f"canonical, as before {recursing * 1e6:.1f} us (ratio {recursing / fast:.1f}x)"
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
    print(f"# at the end: {machine()}")


def machine() -> str:
    """The machine and its load, beside each run's figures."""
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    return f"{platform.machine()}, {os.cpu_count()} cores, load average {load}"


if __name__ == "__main__":
    main()
