"""A cell's statistics (``classification_figures``) and a pooled ``compare`` test: the current
code against its previous form (pair counts searched one non-slip cluster at a time, groups
sorted by ``np.unique``, bootstrap weights drawn again for every figure), in the same run, on
cells shaped like the simulation's (11 000 windows, 120 trials, scores with ties).

    nice python benchmarks/bench_cell_figures.py [--cells 20] > benchmarks/results/cell_figures.txt
"""

from __future__ import annotations

import argparse
import time
from contextlib import contextmanager
from unittest import mock

import numpy as np

from slipbench.stats import bootstrap, metrics
from slipbench.stats.metrics import classification_figures


def old_pair_counts(y, scores, codes, pos, neg):
    s_pos, c_pos = scores[y], np.searchsorted(pos, codes[y])
    out = np.zeros((len(pos), len(neg)))
    for j, d in enumerate(neg):
        ns = np.sort(scores[~y & (codes == d)])
        below = np.searchsorted(ns, s_pos, "left")
        ties = np.searchsorted(ns, s_pos, "right") - below
        out[:, j] = np.bincount(c_pos, weights=below + 0.5 * ties, minlength=len(pos))
    return out


def old_weights(design, seed, n_resamples=bootstrap.N_RESAMPLES):
    return bootstrap._draw_weights(design, seed, n_resamples)


@contextmanager
def previous():
    with (
        mock.patch.object(metrics, "_pair_counts", old_pair_counts),
        mock.patch.object(bootstrap, "resample_weights", old_weights),
        mock.patch.object(bootstrap, "sorted_codes", lambda v: np.unique(v, return_inverse=True)),
    ):
        yield


def cells(n: int) -> list[tuple]:
    rng = np.random.default_rng(0)
    out = []
    for _ in range(n):
        trial = rng.integers(0, 120, 11_000)
        y = (trial % 2).astype(bool)
        score = np.round(1 / (1 + np.exp(-(y - 0.5) * 2 - rng.normal(0, 1, len(y)))), 3)
        groups = np.array([f"trial-{t}" for t in trial], dtype=object)
        out.append((y.astype(np.int8), (score > 0.5).astype(np.int8), groups, score))
    return out


def timed(data: list[tuple]) -> tuple[float, list[dict]]:
    t0 = time.perf_counter()
    out = [classification_figures(y, p, g, seed=0, scores=s) for y, p, g, s in data]
    return (time.perf_counter() - t0) / len(data), out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cells", type=int, default=20)
    data = cells(ap.parse_args().cells)
    timed(data[:1])  # imports and first calls outside the clock
    with previous():
        before, want = timed(data)
    bootstrap._WEIGHTS.clear()
    after, got = timed(data)
    same = all(str(a) == str(b) for a, b in zip(want, got))
    print(f"classification_figures, {len(data)} cells of 11 000 windows and 120 trials")
    print(
        f"previous {before * 1e3:.0f} ms per cell, now {after * 1e3:.0f} ms: {before / after:.1f}x"
    )
    print(f"every figure and interval identical: {same}")


if __name__ == "__main__":
    main()
