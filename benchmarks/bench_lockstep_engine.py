"""The engine's lockstep batches against one model per task: `slipbench evaluate --detector
lstm --protocol window-size` (default scale, --jobs 2), run back to back with
``SLIPBENCH_LOCKSTEP=1`` and ``=0`` into fresh results folders, after a warm-up that builds the
default dataset and numba's caches. Wall seconds, CPU seconds of the command's own process
(RUSAGE_CHILDREN: the pool's workers, children of the fork server, are not in it), the load
average around each run, and whether the two
runs' figures agree, cell by cell. Writes a Markdown table that docs/studies/performance.md includes.

    python benchmarks/bench_lockstep_engine.py [--jobs 2] [--out benchmarks/results/lockstep_engine.md]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parent.parent
FIGURES = ["key", "status", "accuracy", "accuracy_lo", "accuracy_hi", "tp_rate", "tn_rate"]


def evaluate(out: Path, lockstep: bool, extra: list[str]) -> dict:
    """One timed `evaluate` into ``out``: wall and CPU seconds, load before and after."""
    argv = [sys.executable, "-m", "slipbench", "evaluate", "--quiet", "--out", str(out), *extra]
    env = {**os.environ, "SLIPBENCH_LOCKSTEP": "1" if lockstep else "0", "PYTHONPATH": str(ROOT)}
    load = os.getloadavg()[0]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(argv, env=env, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall": wall, "cpu": cpu, "load": (load, os.getloadavg()[0])}


def figures(out: Path) -> pd.DataFrame:
    from slipbench.store.results import ResultsStore

    rows = pd.DataFrame(ResultsStore(out).finished().values())
    return rows[FIGURES].sort_values("key").reset_index(drop=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks/results/lockstep_engine.md")
    args = parser.parse_args()
    run = ["--detector", "lstm", "--protocol", "window-size", "--jobs", str(args.jobs)]
    with tempfile.TemporaryDirectory() as tmp:
        # warm-up: the default dataset, and numba's caches of both training paths
        warm = ["--detector", "lstm", "--protocol", "window-size", "--param", "max_epochs=1"]
        warm += ["--protocol-param", "windows=[50]", "--jobs", "0"]
        for lockstep in (True, False):
            evaluate(Path(tmp, f"warm{lockstep}"), lockstep, warm)
        measured = {on: evaluate(Path(tmp, str(on)), on, run) for on in (True, False)}
        same = figures(Path(tmp, "True")).equals(figures(Path(tmp, "False")))
        cells = len(figures(Path(tmp, "True")))
    on, off = measured[True], measured[False]
    lines = [
        f"`python benchmarks/bench_lockstep_engine.py --jobs {args.jobs}`: `slipbench evaluate "
        f"{' '.join(run)}` (default scale, {cells} cells), with lockstep batches and without "
        f"(`SLIPBENCH_LOCKSTEP=0`), back to back on {os.cpu_count()} CPUs. Figures of every "
        f"cell identical in the two runs: {'yes' if same else 'NO'}.",
        "",
        "| run | wall s | CPU s, main process only | load (1 min) before, after |",
        "|---|---|---|---|",
    ]
    for name, m in (("lockstep batches", on), ("one model per task", off)):
        load = f"{m['load'][0]:.1f}, {m['load'][1]:.1f}"
        lines.append(f"| {name} | {m['wall']:.0f} | {m['cpu']:.0f} | {load} |")
    lines += [
        "",
        f"Speed-up: wall {off['wall'] / on['wall']:.2f}x (CPU of the main process "
        f"{off['cpu'] / on['cpu']:.2f}x; the workers' CPU is not measured).",
    ]
    args.out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
