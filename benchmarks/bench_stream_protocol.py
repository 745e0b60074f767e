"""The streaming protocol's cost against the window-size protocol's, for the same detector on
the same dataset, as a ratio measured in the same run (issue 10's target: under 2).

    python benchmarks/bench_stream_protocol.py [--detector holweg] [--scale 0.05] [--jobs 1]

Each protocol runs from scratch into its own temporary results folder (no cached cell or
model), in this process's order window-size then streaming, after the dataset is read once.
Wall time of ``slipbench.engine.runner.evaluate``; on a shared machine run it twice and keep the lower.
"""

from __future__ import annotations

import argparse
import tempfile
import time

from slipbench.data.defaults import default_dataset
from slipbench.engine.plan import Run
from slipbench.engine.runner import evaluate
from slipbench.store.results import ResultsStore


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--detector", default="holweg")
    parser.add_argument("--scale", type=float, default=0.05)
    parser.add_argument("--jobs", type=int, default=1)
    args = parser.parse_args()
    dataset = default_dataset(args.scale)
    walls = {}
    for protocol in ("window-size", "streaming"):
        with tempfile.TemporaryDirectory() as out:
            t0 = time.perf_counter()
            rows = evaluate(
                dataset,
                Run(args.detector, protocol),
                ResultsStore(out),
                jobs=args.jobs,
                progress=False,
            )
            walls[protocol] = time.perf_counter() - t0
        print(
            f"{protocol:12s} {walls[protocol]:8.1f} s  {len(rows)} cells, {int((rows['status'] == 'ok').sum())} ok"
        )
    print(f"streaming / window-size: {walls['streaming'] / walls['window-size']:.2f} (target < 2)")


if __name__ == "__main__":
    main()
