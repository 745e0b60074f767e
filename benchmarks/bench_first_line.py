"""The README's LSTM command on a fresh install: seconds to its first line and to the bar.

    python benchmarks/bench_first_line.py [--against CHECKOUT] [--out FILE]

Runs ``slipbench evaluate --detector lstm --protocol material-holdout --split grouped
--repeats 3`` (README.md) from this checkout, and with ``--against`` from another one (e.g. a
worktree of the commit before, to compare), one after the other, each with empty caches: a
fresh SLIPBENCH_CACHE (the default dataset is simulated on first use) and a fresh
NUMBA_CACHE_DIR (the LSTM's kernels are compiled). Every line the run prints (stdout and
stderr, a progress bar's updates split at carriage returns) is stamped with the seconds since
the start; a run is stopped (SIGINT to its process group, then SIGKILL) once its bar shows, or
after ``--limit`` seconds. Reported per run: seconds to the first line, to the kernel compile's
notice, to the bar, and the first lines. Wall seconds on a shared machine: the first line
states the machine and its load, before and after.
"""

from __future__ import annotations

import argparse
import os
import platform
import selectors
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = [
    "evaluate",
    "--detector",
    "lstm",
    "--protocol",
    "material-holdout",
    "--split",
    "grouped",
    "--repeats",
    "3",
]
COMPILE = "lstm: compiling"


def stamped(code: Path, limit: float) -> list[tuple[float, str, str]]:
    """(seconds, stream, line) of the README's command run from ``code`` on empty caches,
    until its progress bar shows or ``limit`` seconds pass."""
    with tempfile.TemporaryDirectory(prefix="first-line-") as tmp:
        env = dict(os.environ, PYTHONPATH=str(code), PYTHONUNBUFFERED="1")
        env |= {"SLIPBENCH_CACHE": f"{tmp}/cache", "NUMBA_CACHE_DIR": f"{tmp}/numba"}
        argv = [sys.executable, "-m", "slipbench", *README, "--out", f"{tmp}/results"]
        t0 = time.perf_counter()
        proc = subprocess.Popen(argv, cwd=tmp, env=env, start_new_session=True, **_pipes())
        lines = [
            (t, stream, line.replace(tmp, "TMP")) for t, stream, line in _read(proc, t0, limit)
        ]
        for sig in (signal.SIGINT, signal.SIGKILL):  # the group: the compile child with it
            try:
                os.killpg(proc.pid, sig)
            except ProcessLookupError:
                break
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                continue
        proc.wait()
    return lines


def _pipes() -> dict:
    return {"stdout": subprocess.PIPE, "stderr": subprocess.PIPE}


def _read(proc: subprocess.Popen, t0: float, limit: float) -> list[tuple[float, str, str]]:
    lines: list[tuple[float, str, str]] = []
    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ, "out")  # type: ignore[arg-type]
    sel.register(proc.stderr, selectors.EVENT_READ, "err")  # type: ignore[arg-type]
    open_ = 2
    while open_ and time.perf_counter() - t0 < limit and not _bar(lines):
        for key, _ in sel.select(timeout=0.2):
            data = os.read(key.fileobj.fileno(), 65536)  # type: ignore[union-attr]
            if not data:
                sel.unregister(key.fileobj)
                open_ -= 1
                continue
            now = time.perf_counter() - t0
            text = data.decode(errors="replace").replace("\r", "\n")
            lines += [(now, key.data, line) for line in text.splitlines() if line.strip()]
    return lines


def _bar(lines: list[tuple[float, str, str]]) -> float | None:
    return next((t for t, _, line in lines if "cell/s" in line or "cell]" in line), None)


def _first(lines: list[tuple[float, str, str]], start: str = "") -> float | None:
    return next((t for t, _, line in lines if line.startswith(start)), None)


def _s(t: float | None) -> str:
    return "-" if t is None else f"{t:.1f}"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--against", type=Path, help="another checkout, run after this one")
    ap.add_argument("--limit", type=float, default=1200.0, help="seconds a run may take")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    load = os.getloadavg()[0]
    runs = {"this checkout": ROOT} | ({"--against": args.against} if args.against else {})
    measured = {name: stamped(code, args.limit) for name, code in runs.items()}
    text = [
        "# The README's LSTM command on a fresh install: its first line and its bar\n",
        f"`python benchmarks/bench_first_line.py{' --against CHECKOUT' if args.against else ''}`:"
        f" `slipbench {' '.join(README)}` on empty caches (dataset and numba), each run stopped"
        f" once its bar shows. {platform.machine()}, {os.cpu_count()} cores, Python"
        f" {platform.python_version()}; load average (1 min) {load:.1f} before,"
        f" {os.getloadavg()[0]:.1f} after (other engineers' jobs share these cores: wall"
        " seconds stretch with the load).\n",
        "| run | first line (s) | compile notice (s) | bar (s) |",
        "| --- | --- | --- | --- |",
    ]
    for name, lines in measured.items():
        text.append(
            f"| {name} | {_s(_first(lines))} | {_s(_first(lines, COMPILE))} | {_s(_bar(lines))} |"
        )
    for name, lines in measured.items():
        text += [f"\n{name}, its first lines:\n", "```"]
        text += [f"{t:7.1f} {stream} {line[:110]}" for t, stream, line in lines[:6]]
        text.append("```")
    report = "\n".join(text) + "\n"
    print(report)
    if args.out:
        args.out.write_text(report)


if __name__ == "__main__":
    main()
