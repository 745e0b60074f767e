"""What watching the workers costs: ``Executor(jobs).run`` (a pipe from each worker, jobs
pickled in the parent, a look at the workers every 0.1 s, threads set per worker) against
pebble's ProcessPool fed the same jobs as the engine fed it before (``fit_and_test``, two
tasks per worker in flight, waited on in order), measured in the same run, alternating.
Tasks are quick fits on random windows, so the difference is the executor's own cost.

    python benchmarks/bench_executors.py [--tasks 60] [--jobs 2] [--windows 2000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import multiprocessing
import statistics
import time
from dataclasses import dataclass, field

import numpy as np

from slipbench.detectors.holweg import Holweg
from slipbench.engine.executors import Executor
from slipbench.engine.fitting import Job, TestSet, fit_and_test


@dataclass
class Task:
    cells: list = field(default_factory=lambda: [None])


def jobs_of(n_windows: int) -> Job:
    rng = np.random.default_rng(0)
    x = rng.normal(size=(n_windows, 50)).astype(np.float32)
    y = np.tile([0, 1], n_windows // 2).astype(np.int8)
    test = TestSet(x, y, np.arange(n_windows) % 20)
    return Job(Holweg(), 0, 1000.0, x, y, [test])


def reference(tasks: list[Task], job: Job, jobs: int) -> float:
    """The engine's loop before the watch: pebble alone."""
    from pebble import ProcessPool

    t0 = time.perf_counter()
    context = multiprocessing.get_context("forkserver")
    with ProcessPool(max_workers=jobs, context=context) as pool:
        pending: list = []
        queue = iter(tasks)
        while True:
            for _ in queue:
                pending.append(pool.schedule(fit_and_test, args=(job,)))
                if len(pending) >= 2 * jobs:
                    break
            if not pending:
                break
            pending.pop(0).result()
    return time.perf_counter() - t0


def watched(tasks: list[Task], job: Job, jobs: int) -> float:
    t0 = time.perf_counter()
    for _ in Executor(jobs).run(tasks, lambda task: job):
        pass
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", type=int, default=60)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--windows", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    tasks, job = [Task() for _ in range(args.tasks)], jobs_of(args.windows)
    times: dict[str, list[float]] = {"pebble alone": [], "Executor.run": []}
    for _ in range(args.repeats):
        times["pebble alone"].append(reference(tasks, job, args.jobs))
        times["Executor.run"].append(watched(tasks, job, args.jobs))
    base = statistics.median(times["pebble alone"])
    print(f"{args.tasks} tasks of {args.windows} windows, {args.jobs} workers, pool start included")
    for name, runs in times.items():
        median = statistics.median(runs)
        print(f"  {name:14s} median {median:6.2f} s  ({median / base:.2f} x pebble alone)")


if __name__ == "__main__":
    main()
