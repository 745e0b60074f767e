"""What the audit hook of :mod:`slipbench.store.reads` costs a fit: holweg fitted on toy
windows in two fresh processes, one that never installs the hook and one that fits under
:func:`~slipbench.store.reads.reading` (as the engine does), alternated, best of ``--repeats``.

    nice python benchmarks/bench_read_hook.py --windows 2000 --window 100 --repeats 5

Prints the fit seconds of each and their ratio (with / without), both from the same invocation,
and the number of audit events one fit raises: the hook's work, whatever the machine's load.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

CHILD = """
import json, sys, time
from slipbench.engine.registry import detectors
from slipbench.store.reads import reading
from slipbench.testing import toy

hooked, n, length, repeats = sys.argv[1] == "1", *map(int, sys.argv[2:])
x, y = toy("univariate", n, length)
cls = detectors.get("holweg")
events = []
if hooked:  # a second hook counts the audit events one fit raises: what the first one sees
    sys.addaudithook(lambda event, args: events.append(event))
best = float("inf")
for _ in range(repeats):
    events.clear()
    detector = cls()
    t0 = time.perf_counter()
    if hooked:
        with reading():
            detector.fit(x, y, sampling_rate=1000.0, seed=0)
    else:
        detector.fit(x, y, sampling_rate=1000.0, seed=0)
    best = min(best, time.perf_counter() - t0)
print(json.dumps([best, len(events)]))
"""


def fit_seconds(hooked: bool, n: int, length: int, repeats: int) -> tuple[float, int]:
    argv = [sys.executable, "-c", CHILD, str(int(hooked)), str(n), str(length), str(repeats)]
    out = subprocess.run(argv, check=True, capture_output=True, text=True).stdout
    best, events = json.loads(out.strip().splitlines()[-1])
    return float(best), int(events)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--windows", type=int, default=2000)
    parser.add_argument("--window", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    without, with_hook, events = [], [], 0
    for _ in range(args.rounds):  # alternated, so load on the machine hits both alike
        without.append(fit_seconds(False, args.windows, args.window, args.repeats)[0])
        seconds, events = fit_seconds(True, args.windows, args.window, args.repeats)
        with_hook.append(seconds)
    a, b = min(without), min(with_hook)
    print(
        f"holweg fit, {args.windows} windows of {args.window}: best of {args.rounds}x{args.repeats}"
    )
    print(f"without the hook {a:.4f} s, with it (recording) {b:.4f} s, ratio {b / a:.3f}")
    print(f"audit events one fit raises (each one context-variable lookup): {events}")


if __name__ == "__main__":
    main()
