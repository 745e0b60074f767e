"""Where the time of a long history's step search goes: one series of ``--points`` runs.

``history steps`` cuts every series with ``ruptures.Binseg`` under the interval-weighted cost
(:func:`slipbench.history.steps.propose`). Against it, in the same run, ruptures' compiled
search: ``KernelCPD`` with the linear kernel (the unweighted L2 cost, searched by Pelt in C).
Each is timed on a series with three 3-point steps and on a flat one (1 point of noise), and
the time of a history of ``--series`` such series on ``--jobs`` cores is projected from them
(the search alone: loading and confirming come on top).

    python benchmarks/bench_step_search.py [--points 10000] [--series 906] [--jobs 2]
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

import numpy as np
import ruptures as rpt

from slipbench.history.steps import MIN_RUNS, PENALTY, propose
from slipbench.seeding import rng_for


def series(points: int, stepped: bool) -> np.ndarray:
    value = 0.8 + 0.01 * rng_for(points, "step-search", stepped).standard_normal(points)
    if stepped:
        for at in (points // 4, points // 2, 3 * points // 4):
            value[at:] -= 0.03
    return value


def timed(search, value: np.ndarray) -> tuple[float, list[int]]:
    start = time.perf_counter()
    found = search(value)
    return time.perf_counter() - start, found


def weighted(value: np.ndarray) -> list[int]:
    return propose(value, np.full(len(value), 0.01))


def compiled(value: np.ndarray) -> list[int]:
    z = (value / 0.01).reshape(-1, 1)  # in units of the points' standard error
    algo = rpt.KernelCPD(kernel="linear", min_size=MIN_RUNS, jump=1).fit(z)
    return [int(b) for b in algo.predict(pen=PENALTY * math.log(len(value)))[:-1]]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=10_000)
    parser.add_argument("--series", type=int, default=906)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--out", type=Path)
    a = parser.parse_args()
    lines = []
    for name, search in (("Binseg, weighted cost (slipbench)", weighted), ("KernelCPD linear, Pelt in C", compiled)):  # fmt: skip
        took = {}
        for stepped in (True, False):
            took[stepped], found = timed(search, series(a.points, stepped))
            if stepped:
                cuts = found
        mean = (took[True] + took[False]) / 2
        lines.append(
            f"| {name} | {1000 * took[True]:.0f} | {1000 * took[False]:.0f} | {cuts} | "
            f"{mean * a.series / a.jobs:.0f} |"
        )
    text = (
        f"The step search on one series of {a.points} runs:\n\n"
        "| search | 3 steps (ms) | flat (ms) | cuts found (of the 3 steps) | "
        f"{a.series} series on {a.jobs} cores (s, projected) |\n|---|---|---|---|---|\n"
        + "\n".join(lines)
        + f"\n\n{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the end.\n"
    )
    print(text)
    if a.out:
        a.out.write_text(text)


if __name__ == "__main__":
    main()
