"""Reader and fingerprint cost on the simulated design at scale 0.2 (12 M samples, 46 M values),
against references measured in the same run: pyarrow reading the same two files into a table
(no checks, no placing), and BLAKE2b over the files' bytes (the old, byte-based fingerprint).
Also the reader on the same files with the rows of samples.parquet shuffled.

    python benchmarks/bench_data.py [--scale 0.2]
"""

from __future__ import annotations

import argparse
import hashlib
import tempfile
import timeit
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from slipbench.data.fingerprint import content_fingerprint
from slipbench.data.read import read_dataset
from slipbench.data.schema import RECORDINGS_FILE, SAMPLES_FILE
from slipbench.data.synth import synthesize


def best_of(fn, repeats: int = 3) -> float:
    """The fastest of ``repeats`` calls, in seconds (the least disturbed by other work)."""
    return min(timeit.repeat(fn, number=1, repeat=repeats))


def file_hash(path: Path) -> str:
    h = hashlib.blake2b(digest_size=8)
    for name in (RECORDINGS_FILE, SAMPLES_FILE):
        with open(path / name, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 22), b""):
                h.update(block)
    return h.hexdigest()


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--scale", type=float, default=0.2)
    scale = parser.parse_args().scale
    with tempfile.TemporaryDirectory() as tmp:
        path = synthesize(Path(tmp) / "ds", scale, 0)
        ds = read_dataset(path)
        values = sum(a.size for a in ds.samples.values())
        print(
            f"scale {scale:g}: {len(ds.recordings)} recordings, {sum(len(a) for a in ds.samples.values()) / 1e6:.1f} M samples, "
            f"{values / 1e6:.1f} M values"
        )
        arrow = best_of(
            lambda: (pq.read_table(path / RECORDINGS_FILE), pq.read_table(path / SAMPLES_FILE))
        )
        print(f"reference: pyarrow read_table of both files: {arrow:.2f} s")
        read = best_of(lambda: read_dataset(path))
        print(
            f"read_dataset (checks, places by sample_index): {read:.2f} s = {read / arrow:.1f} x read_table"
        )
        shuffled = Path(tmp) / "shuffled"
        shuffled.mkdir()
        table = pq.read_table(path / SAMPLES_FILE)
        pq.write_table(
            table.take(np.random.default_rng(0).permutation(table.num_rows)),
            shuffled / SAMPLES_FILE,
            row_group_size=1 << 20,
        )
        pq.write_table(pq.read_table(path / RECORDINGS_FILE), shuffled / RECORDINGS_FILE)
        del table
        read_shuffled = best_of(lambda: read_dataset(shuffled), repeats=1)
        print(
            f"read_dataset, sample rows shuffled: {read_shuffled:.2f} s = {read_shuffled / arrow:.1f} x read_table"
        )
        raw = best_of(lambda: file_hash(path))
        print(f"reference: BLAKE2b of the files' bytes: {raw:.2f} s")
        content = best_of(lambda: content_fingerprint(ds.recordings, ds.samples, ds.slip_labels))
        print(
            f"content fingerprint: {content:.2f} s = {content / raw:.1f} x hashing the bytes "
            f"({values / content / 1e6:.0f} M values/s)"
        )


if __name__ == "__main__":
    main()
