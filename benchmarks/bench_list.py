"""``slipbench list`` against an import of pandas, in the same run.

    python benchmarks/bench_list.py [--runs 7] [--out FILE]

Each runs as a whole process, alternately (A B A B ..., so that a machine whose speed drifts
moves both), after one warm-up of each: ``python -m slipbench list`` (this checkout's code),
``list --check`` (every plugin imported, as ``list`` did before it read their source) and the
reference ``python -c "import pandas"``. Per command: CPU seconds (the child's user + system,
from ``os.wait4``), best and median, the ratio of the medians to the reference's (the target
for ``list``: at most 0.5) and peak memory. The first line says the machine and its load.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
COMMANDS = {
    "import pandas (reference)": [sys.executable, "-c", "import pandas"],
    "slipbench list": [sys.executable, "-m", "slipbench", "list"],
    "slipbench list --check": [sys.executable, "-m", "slipbench", "list", "--check"],
}


def timed(argv: list[str]) -> tuple[float, float]:
    """(CPU s, peak MB) of one run of ``argv`` as a child process."""
    proc = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, _, usage = os.wait4(proc.pid, 0)
    proc.returncode = 0  # reaped above
    return usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    load_before = os.getloadavg()[0]
    got: dict[str, list[tuple[float, float]]] = {name: [] for name in COMMANDS}
    for i in range(args.runs + 1):
        for name, argv in COMMANDS.items():
            measured = timed(argv)
            if i:  # the first round warms the file cache
                got[name].append(measured)
    reference = statistics.median(c for c, _ in got["import pandas (reference)"])
    lines = [
        "| command | CPU best (s) | CPU median (s) | median / reference | peak (MB) |",
        "| --- | --- | --- | --- | --- |",
    ]
    for name, runs in got.items():
        cpus = [c for c, _ in runs]
        lines.append(
            f"| {name} | {min(cpus):.3f} | {statistics.median(cpus):.3f} "
            f"| {statistics.median(cpus) / reference:.2f} | {max(m for _, m in runs):.0f} |"
        )
    head = (
        f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"load average {load_before:.1f} before and {os.getloadavg()[0]:.1f} after "
        f"(other engineers' jobs share these cores), {args.runs} runs each"
    )
    report = "# slipbench list against an import of pandas\n\n" + head + "\n\n"
    report += "\n".join(lines) + "\n"
    print(report)
    if args.out:
        args.out.write_text(report)


if __name__ == "__main__":
    main()
