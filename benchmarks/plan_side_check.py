"""The gate's plan of a side (``run FILE --plan``: "cost of a side") against a side measured
right after it: the bench file (default: the shipped ``bench.toml``) copied into a temporary
folder, calibrated there on its first look's seeds (``--seeds``, default its ``repeats``; the
shipped calibration is left alone), planned, then run as the workflow runs a side
(``slipbench run FILE --out DIR --quiet``, timed as one command, the dataset already cached).

    python benchmarks/plan_side_check.py [BENCH] [--seeds N] > benchmarks/results/plan_side.md
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from slipbench.app.benchspec import load_benchmark
from slipbench.app.gateplan import SIDE_PARTS, side_seconds
from slipbench.gate.calibration import read_calibration

ROOT = Path(__file__).resolve().parents[1]


def slipbench(*args: str) -> float:
    """Seconds of one ``python -m slipbench ARGS`` (its output dropped)."""
    t0 = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "slipbench", *args], check=True, stdout=subprocess.DEVNULL
    )
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("bench", nargs="?", type=Path, default=ROOT / "bench.toml")
    ap.add_argument("--seeds", type=int, help="seeds to calibrate [default: its repeats]")
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="plan-side-"))
    try:
        bench_file = work / args.bench.name
        shutil.copy(args.bench, bench_file)
        bench = load_benchmark(bench_file)
        seeds = args.seeds or max(bench.repeats, 2)
        load = [os.getloadavg()[0]]
        calibrated = slipbench("calibrate", str(bench_file), "--seeds", str(seeds), "--quiet")
        cal = read_calibration(bench.calibration_file)
        planned, counted = side_seconds(bench.repeats, cal.wall_seconds_per_seed, cal.side)
        models_only = bench.repeats * cal.wall_seconds_per_seed
        # a calibration of a few seeds may refuse the bench's gate: the side runs without it
        bench.calibration_file.rename(work / "measured.calibration.json")
        measured = slipbench("run", str(bench_file), "--out", str(work / "side"), "--quiet")
        load.append(os.getloadavg()[0])
    finally:
        shutil.rmtree(work, ignore_errors=True)
    parts = ", ".join(f"{w} {cal.side[k]:.1f} s" for k, w in SIDE_PARTS.items())
    print(
        f"`run --plan`'s cost of a side against the side measured right after (`slipbench run "
        f"{args.bench.name} --quiet`, one command, the dataset cached), on "
        f"{os.cpu_count()} processors ({platform.machine()}), load average {load[0]:.2f} "
        f"before and {load[1]:.2f} after; calibrated on {seeds} seeds in {calibrated:.0f} s.\n"
    )
    print("| estimate | seconds | ratio to measured |\n| --- | --- | --- |")
    print(f"| measured side, {bench.repeats} seeds | {measured:.1f} | 1.00 |")
    print(f"| plan, models only (before) | {models_only:.1f} | {models_only / measured:.2f} |")
    print(
        f"| plan, counting start, data and reports{'' if counted else ' (not measured)'} "
        f"| {planned:.1f} | {planned / measured:.2f} |"
    )
    print(f"\nThe calibration's parts: {parts}, models {cal.wall_seconds_per_seed:.1f} s a seed.")


if __name__ == "__main__":
    main()
