"""The whole paper as issue 55 times it: `slipbench evaluate --detector all --protocol all
--jobs 2` (no aeon), the default dataset simulated first into an empty cache, once with the
numba cache warm and once cold (an empty NUMBA_CACHE_DIR: a fresh install). Wall and CPU
seconds (the process tree's), peak resident memory, the machine's load before and after.

    python benchmarks/bench_whole_paper.py [--jobs 2] [--cache warm cold] [--against TREE]
        [--out benchmarks/results/whole_paper.md]

``--against TREE``: each run also with an earlier checkout's code (its source first on
PYTHONPATH), the earlier first, so that the two are measured in one session.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil


def run(env: dict[str, str], jobs: int, out: Path) -> dict[str, float]:
    argv = [sys.executable, "-m", "slipbench", "evaluate", "--detector", "all"]
    argv += ["--protocol", "all", "--jobs", str(jobs), "--out", str(out), "--quiet"]
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        argv,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tempfile.gettempdir(),
    )
    root, peak = psutil.Process(proc.pid), 0
    cpu: dict[int, float] = {}  # each process's last CPU seconds seen: workers exit unreaped
    while proc.poll() is None:
        try:
            tree = [root, *root.children(recursive=True)]
            peak = max(peak, sum(p.memory_info().rss for p in tree))
            for p in tree:
                t = p.cpu_times()
                cpu[p.pid] = t.user + t.system
        except psutil.Error:
            pass
        time.sleep(0.1)
    wall = time.perf_counter() - t0
    if proc.returncode:
        raise SystemExit(
            f"exit {proc.returncode}: {proc.stderr.read()[-2000:] if proc.stderr else ''}"
        )
    return {"wall": wall, "cpu": sum(cpu.values()), "peak_gb": peak / 2**30}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--cache", nargs="+", choices=["warm", "cold"], default=["warm"])
    ap.add_argument("--against", type=Path, help="an earlier checkout to run first")
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results/whole_paper.md"))
    a = ap.parse_args()
    lines = [
        f"# The whole paper: `evaluate --detector all --protocol all --jobs {a.jobs}`",
        "",
        f"{platform.machine()}, {psutil.cpu_count()} cores, Python {platform.python_version()}; "
        "the default dataset (scale 0.05) simulated first into an empty cache in each run.",
        "",
        "| code | numba cache | wall | CPU (the process tree, sampled every 0.1 s) | peak RSS (the tree summed) | load before -> after |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    kinds = a.cache  # cold: an empty NUMBA_CACHE_DIR; an earlier tree's kernels are cold anyway
    trees = [("this", None)] if a.against is None else [("earlier", a.against), ("this", None)]
    with tempfile.TemporaryDirectory() as tmp:
        for kind, (code, tree) in ((k, t) for k in kinds for t in trees):
            env = dict(os.environ, SLIPBENCH_CACHE=str(Path(tmp, code, kind, "cache")))
            if tree is not None:
                env["PYTHONPATH"] = str(tree.resolve())
            if kind == "cold":
                env["NUMBA_CACHE_DIR"] = str(Path(tmp, code, kind, "numba"))
            before = os.getloadavg()[0]
            m = run(env, a.jobs, Path(tmp, code, kind, "results"))
            after = os.getloadavg()[0]
            lines.append(
                f"| {code} | {kind} | {m['wall'] / 60:.0f} min {m['wall'] % 60:02.0f} s | "
                f"{m['cpu'] / 60:.1f} CPU-min | {m['peak_gb']:.2f} GB | {before:.1f} -> {after:.1f} |"
            )
            print(lines[-1], flush=True)
    a.out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
