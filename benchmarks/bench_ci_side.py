"""What one side of the CI gate costs: ``slipbench run`` of the shipped ``bench.toml`` against the
bench it replaced (issue 35's: window-size at windows 50 and 100 and cross-instance, 1 point per
figure), each at its first look's seeds and, for the shipped one, at each further look of its
budget, timed in the same run, alternating, on a warm dataset cache. A CI side is what the
workflow runs per branch; the ratio to the old bench's side is what a pull request waits for
more (or less).

    nice python benchmarks/bench_ci_side.py [--rounds 2] > benchmarks/results/ci_side.md
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from slipbench.app.benchspec import load_benchmark

ROOT = Path(__file__).resolve().parents[1]
OLD = """\
[benchmark]
out = "results"
report = ["md", "html"]
plots = false
intervals = true
[dataset]
scale = 0.05
seed = 0
[run]
split = "grouped"
seed = 0
repeats = 3
jobs = 2
[gate]
accuracy = 1.0
tn_rate = 1.0
tp_rate = 1.0
[detectors.holweg]
[detectors.bandpass]
[protocols.window-size]
windows = [50, 100]
[protocols.cross-instance]
"""


def side(bench: Path, out: Path, seed: int) -> float:
    """Seconds of one ``slipbench run`` (a CI side) into a fresh folder."""
    t0 = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "slipbench", "run", str(bench), "--out", str(out), "--quiet",
         "--seed", str(seed)],
        check=True,
        stdout=subprocess.DEVNULL,
    )  # fmt: skip
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=2, help="runs of each side, alternating")
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="ci-side-"))
    old = work / "old.toml"
    old.write_text(OLD)
    new = ROOT / "bench.toml"
    text = new.read_text()
    shipped = load_benchmark(new)
    repeats = shipped.repeats
    looks = [*range(repeats, shipped.seeds_budget, repeats), shipped.seeds_budget]
    benches = {"issue 35's bench, 3 seeds": (old, 3)}
    for seeds in looks:
        path = work / f"new-{seeds}.toml"
        path.write_text(text.replace(f"repeats = {repeats}", f"repeats = {seeds}", 1))
        benches[f"bench.toml, {seeds} seeds"] = (path, seeds)
    side(old, work / "warm", 0)  # the dataset simulated into the cache before any timing
    load = os.getloadavg()[0]
    times: dict[str, list[float]] = {name: [] for name in benches}
    for r in range(args.rounds):
        for name, (path, _) in benches.items():
            times[name].append(side(path, work / f"{path.stem}-{r}", 0))
    base = float(np.median(times["issue 35's bench, 3 seeds"]))
    print(f"One CI side (`slipbench run`, reports included), {args.rounds} rounds alternating; "
          f"{os.cpu_count()} processors, load average {load:.1f} before and "
          f"{os.getloadavg()[0]:.1f} after (a shared machine: the ratios are the figures).\n")  # fmt: skip
    print("| side | seeds | seconds (median) | ratio to issue 35's side |")
    print("| --- | --- | --- | --- |")
    for name, (_, seeds) in benches.items():
        m = float(np.median(times[name]))
        print(f"| {name} | {seeds} | {m:.0f} | {m / base:.2f} |")


if __name__ == "__main__":
    main()
