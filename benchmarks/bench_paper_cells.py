"""The cheap detectors' cells of the paper (issue 55): CPU time of ``slipbench evaluate`` in this
checkout against an earlier one, runs alternated, in one session; and the two runs' results
compared figure by figure.

Both checkouts run the same command in a child process (``--jobs 0``: the cells' work and the
main process's in one process, so the children's CPU time holds both), on one simulated
dataset synthesized first. CPU time, not wall: the machine may be shared.

    git worktree add /tmp/before <commit>
    nice python benchmarks/bench_paper_cells.py --before /tmp/before [--rounds 2] \\
        [--detector holweg,bandpass,features] [--protocol all] > benchmarks/results/paper_cells.md
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

#: what names a row: its key holds the code's identity, which the change itself changes
NAMES = ["protocol", "detector", "split", "seed", "cell"]
#: columns that say when or how fast a cell ran, or which code ran it, not what it found
TIMING = {
    "key",
    "model_key",
    "code_identity",
    "run_id",
    "finished_at",
    "train_s",
    "test_s",
    "stream_s",
    "train_us_per_sample",
    "infer_us_per_window",
    "peak_mem_mb",
    "compute_ms_per_hop",
    "realtime",
}


def run(tree: Path, out: Path, args: argparse.Namespace, cache: Path) -> tuple[float, float]:
    """CPU seconds (user + system) and wall seconds of one evaluate in ``tree``."""
    env = {**os.environ, "PYTHONPATH": str(tree), "SLIPBENCH_CACHE": str(cache)}
    command = [sys.executable, "-m", "slipbench", "evaluate", "--detector", args.detector]
    command += ["--protocol", args.protocol, "--jobs", "0", "--quiet", "--out", str(out)]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(command, cwd=tree, env=env, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, wall


def same_value(a: object, b: object) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return (np.isnan(a) and np.isnan(b)) or a == b
    return bool(a == b) if not (a is None or b is None) else a is b


def compare(old: Path, new: Path) -> list[str]:
    """Lines saying whether the two results files hold the same rows, value for value."""
    a = pd.read_parquet(old / "results.parquet").set_index(NAMES)
    b = pd.read_parquet(new / "results.parquet").set_index(NAMES)
    same_cells = set(a.index) == set(b.index) and a.index.is_unique
    lines = [f"rows: {len(a)} before, {len(b)} after; the same cells: {same_cells}"]
    columns = sorted((set(a.columns) & set(b.columns)) - TIMING)
    differ = {}
    for c in columns:
        x, y = a[c].reindex(b.index), b[c]
        bad = [i for i in range(len(b)) if not same_value(x.iloc[i], y.iloc[i])]
        if bad:
            differ[c] = len(bad)
    lines.append(
        f"columns compared: {len(columns)} (timing columns left out: {', '.join(sorted(TIMING))})"
    )
    lines.append(
        "every value identical (floats to the last bit)"
        if not differ
        else "differing: " + ", ".join(f"{c} ({n} rows)" for c, n in sorted(differ.items()))
    )
    only = sorted(set(a.columns) ^ set(b.columns))
    if only:
        lines.append(f"columns in one file only: {', '.join(only)}")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--before", type=Path, required=True, help="the earlier checkout")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--detector", default="holweg,bandpass,features")
    parser.add_argument("--protocol", default="all")
    args = parser.parse_args()
    here = Path(__file__).resolve().parents[1]
    trees = {"before": args.before.resolve(), "after": here}
    with tempfile.TemporaryDirectory() as tmp:
        cache, times = Path(tmp) / "cache", {k: [] for k in trees}
        run(here, Path(tmp) / "warm", argparse.Namespace(**{**vars(args), "protocol": "window-size", "detector": "holweg"}), cache)  # fmt: skip
        load = os.getloadavg()
        for i in range(args.rounds):
            order = list(trees) if i % 2 == 0 else list(trees)[::-1]
            for name in order:
                times[name].append(run(trees[name], Path(tmp) / f"{name}-{i}", args, cache))
        load_end = os.getloadavg()
        lines = compare(Path(tmp) / "before-0", Path(tmp) / "after-0")
    cmd = f"slipbench evaluate --detector {args.detector} --protocol {args.protocol} --jobs 0"
    print(f"# {cmd}: this checkout against {args.before.name}\n")
    print(
        f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}; shared (load average at start "
        f"{', '.join(f'{v:.1f}' for v in load)}, at end {', '.join(f'{v:.1f}' for v in load_end)})."
        f" Default dataset (scale 0.05), synthesized before the runs; {args.rounds} rounds, "
        "before and after alternated. CPU time: user + system of the child process.\n"
    )
    print("| run | CPU s (each round) | wall s (each round) |\n|:--|--:|--:|")
    for name, ts in times.items():
        print(
            f"| {name} | {', '.join(f'{c:.1f}' for c, _ in ts)} | "
            f"{', '.join(f'{w:.0f}' for _, w in ts)} |"
        )
    ratio = np.median([c for c, _ in times["before"]]) / np.median([c for c, _ in times["after"]])
    print(f"\nCPU time before / after (medians): {ratio:.2f}x\n")
    print("Results of round 0, before against after:\n")
    for line in lines:
        print(f"- {line}")


if __name__ == "__main__":
    main()
