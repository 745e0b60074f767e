"""The LSTM's kernels from an empty numba cache: compiled once, however many processes start.

    python benchmarks/bench_lstm_compile.py [--out FILE]

In a fresh NUMBA_CACHE_DIR (a temporary folder), two processes start at once, each asking for
the kernels a run of ``evaluate`` calls (``lstm_compile.ready("predict", "lockstep")``, what
each pool worker of ``--jobs 2`` does before its first model); then a third process asks again.
Before slipbench serialized the compile, both of the first two compiled (each its own 68.7 CPU
s and 917 MB at least); now one compiles and the other waits, then loads. Per process: CPU
seconds (user + system, from ``os.wait4``), wall seconds and peak memory; the ratios of the
second process's and the third's CPU to the compiling one's (a load, not a compile, is well
under 0.05). The first line says the machine and its load: CPU time, not wall time, is the
figure to read on a shared machine.
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

ROOT = Path(__file__).resolve().parents[1]
ASK = "from slipbench.detectors import lstm; lstm.lstm_compile.ready('predict', 'lockstep')"


def start(env: dict[str, str]) -> tuple[subprocess.Popen, float]:
    return subprocess.Popen([sys.executable, "-c", ASK], cwd=ROOT, env=env), time.perf_counter()


def reap(proc: subprocess.Popen, t0: float) -> tuple[float, float, float]:
    """(CPU s, wall s, peak MB) of a child started at ``t0``."""
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        raise SystemExit(f"a process exited with {proc.returncode}")
    return usage.ru_utime + usage.ru_stime, time.perf_counter() - t0, usage.ru_maxrss / 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        pair = [start(env), start(env)]  # two workers of --jobs 2, at once
        first, second = (reap(*p) for p in pair)
        third = reap(*start(env))  # a later run: the cache is warm
    compiled = max(first, second)  # the one that compiled spent the CPU
    loaded = min(first, second)
    rows = [("compiled (one of two at once)", compiled), ("waited, then loaded", loaded)]
    rows.append(("a later process", third))
    lines = [
        "| process | CPU (s) | wall (s) | peak (MB) | CPU / the compile's |",
        "| --- | --- | --- | --- | --- |",
    ]
    lines += [
        f"| {n} | {c:.1f} | {w:.1f} | {m:.0f} | {c / compiled[0]:.4f} |" for n, (c, w, m) in rows
    ]
    head = (
        f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"load average {load_before:.1f} before and {os.getloadavg()[0]:.1f} after "
        "(other engineers' jobs share these cores: read the CPU seconds)"
    )
    report = (
        f"# The LSTM's kernels from an empty numba cache\n\n{head}\n\n" + "\n".join(lines) + "\n"
    )
    print(report)
    if args.out:
        args.out.write_text(report)


if __name__ == "__main__":
    main()
