"""How the whole paper's cost grows with the dataset: wall time and peak memory of
`slipbench evaluate --protocol all` at several scales, a second (cached) run, and a linear
extrapolation of peak memory to scale 1.0.

    python benchmarks/bench_scale.py [--detector all] [--scales 0.05 0.1 0.2] [--jobs 1]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import psutil


def measure(argv: list[str]) -> tuple[float, float]:
    """Wall seconds and peak resident memory (GiB, the process tree summed) of a command."""
    t0 = time.perf_counter()
    # outside the source tree, so that `slipbench` is the installed package
    proc = subprocess.Popen(
        argv,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tempfile.gettempdir(),
    )
    root, peak = psutil.Process(proc.pid), 0
    while proc.poll() is None:
        try:
            tree = [root, *root.children(recursive=True)]
            peak = max(peak, sum(p.memory_info().rss for p in tree))
        except psutil.Error:
            pass
        time.sleep(0.05)
    if proc.returncode:
        raise SystemExit(f"{' '.join(argv)} failed:\n{proc.stderr.read()}")
    return time.perf_counter() - t0, peak / 2**30


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--detector", default="holweg")
    parser.add_argument("--scales", type=float, nargs="+", default=[0.05, 0.1, 0.2])
    parser.add_argument("--jobs", type=int, default=1)
    args = parser.parse_args()
    cli = [sys.executable, "-m", "slipbench.app.cli"]
    peaks = []
    print(f"detector {args.detector}, protocol all, jobs {args.jobs}")
    print("| scale | samples/unit | synth s | evaluate s | cached rerun s | peak GiB |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for scale in args.scales:
            data, out = Path(tmp) / f"d{scale:g}", Path(tmp) / f"r{scale:g}"
            synth_s, _ = measure(cli + ["dataset", "synth", str(data), "--scale", str(scale)])
            run = cli + [
                "evaluate",
                "--detector",
                args.detector,
                "--protocol",
                "all",
                "--dataset",
                str(data),
                "--out",
                str(out),
                "--quiet",
                "--jobs",
                str(args.jobs),
            ]
            wall, peak = measure(run)
            cached, _ = measure(run)
            peaks.append(peak)
            print(
                f"| {scale:g} | {8e6 * scale / 1e6:.1f} M | {synth_s:.1f} | {wall:.1f} | {cached:.1f} | {peak:.2f} |"
            )
    if len(peaks) > 1:
        slope, intercept = np.polyfit(args.scales, peaks, 1)
        print(
            f"\npeak memory ~ {intercept:.2f} + {slope:.2f} x scale GiB: {intercept + slope:.2f} GiB extrapolated to scale 1.0"
        )


if __name__ == "__main__":
    main()
