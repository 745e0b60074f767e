"""The fixed costs of the command line against importing pandas and pyarrow, in the same run.

    python benchmarks/bench_fixed_costs.py [--runs 5] [--out FILE] [--label TEXT]

Each command runs as a whole process, alternately with the reference
``python -c "import pandas, pyarrow.parquet"`` (A B A B ..., so that a machine whose speed
drifts moves both), after one warm-up of each: ``slipbench --version``, an unknown detector's
error (``evaluate --detector holwge``) and a fully cached rerun of a 48-cell window-size run
(holweg on the default dataset at scale 0.05: 8 units x 6 windows; the first run, not timed,
computes the cells into a temporary folder). Per command: its wall and CPU seconds (the child's
user + system time, from ``os.wait4``), best and median over the runs, and the ratio to the
reference's best (the targets: at most 0.5 for the first two, 4 for the rerun). The first line
says the machine, its load and whether Python may cache bytecode (``PYTHONDONTWRITEBYTECODE``:
without cached bytecode every slipbench module is compiled again in every process).
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REFERENCE = [sys.executable, "-c", "import pandas, pyarrow.parquet"]
TARGETS = {"--version": 0.5, "unknown detector": 0.5, "cached 48-cell rerun": 4.0}


def _slipbench(*args: str) -> list[str]:
    return [sys.executable, "-m", "slipbench", *args]


def timed(argv: list[str], cwd: Path) -> tuple[float, float]:
    """(wall, CPU) seconds of one run of ``argv`` as a child process."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(argv, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, _, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = 0  # reaped above
    return wall, usage.ru_utime + usage.ru_stime


def measure(commands: dict[str, list[str]], runs: int, cwd: Path) -> dict[str, list]:
    """Every command and the reference in turn, ``runs`` times after a warm-up of each."""
    out: dict[str, list] = {name: [] for name in ["reference", *commands]}
    for i in range(runs + 1):
        for name, argv in commands.items():
            for label, command in (("reference", REFERENCE), (name, argv)):
                got = timed(command, cwd)
                if i:  # the first round warms the file cache
                    out[label].append(got)
    return out


def table(times: dict[str, list]) -> str:
    best_ref = min(w for w, _ in times["reference"]), min(c for _, c in times["reference"])
    lines = [
        "| command | wall best (s) | wall median (s) | CPU best (s) | CPU median (s) "
        "| wall / reference (best) | CPU / reference (best) | target |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for name, got in times.items():
        walls, cpus = [w for w, _ in got], [c for _, c in got]
        lines.append(
            f"| {name} | {min(walls):.3f} | {statistics.median(walls):.3f} | {min(cpus):.3f} "
            f"| {statistics.median(cpus):.3f} | {min(walls) / best_ref[0]:.2f} "
            f"| {min(cpus) / best_ref[1]:.2f} | {TARGETS.get(name, '')} |"
        )
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--out", type=Path)
    ap.add_argument("--label", default="", help="what code ran, for the first line")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        cwd = Path(tmp)  # not the repository root, whose slipbench/ would shadow the install
        rerun = _slipbench("evaluate", "--detector", "holweg", "--protocol", "window-size")
        rerun += ["--out", str(cwd / "results"), "--quiet"]
        subprocess.run(rerun + ["--jobs", "2"], cwd=cwd, check=True, stdout=subprocess.DEVNULL)
        commands = {
            "--version": _slipbench("--version"),
            "unknown detector": _slipbench("evaluate", "--detector", "holwge", "--protocol", "x"),
            "cached 48-cell rerun": rerun,
        }
        times = measure(commands, args.runs, cwd)
        shutil.rmtree(cwd / "results")
    bytecode = "no" if os.environ.get("PYTHONDONTWRITEBYTECODE") else "yes"
    head = (
        (f"{args.label}: " if args.label else "")
        + f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"load average {os.getloadavg()[0]:.1f} at the end, {args.runs} runs each, "
        f"bytecode cached: {bytecode}"
    )
    report = f"# Fixed costs of the command line\n\n{head}\n\n{table(times)}\n"
    print(report)
    if args.out:
        args.out.write_text(report)


if __name__ == "__main__":
    main()
