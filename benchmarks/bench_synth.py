"""What the simulation costs: wall time and peak memory of ``generate`` at a scale, for this
model and, beside it in the same run, an earlier one given as its ``synth.py`` (e.g. written by
``git show <commit>:slipbench/data/synth.py > old_synth.py``). Each measurement runs in a fresh
process (imports excluded from the time, peak resident memory of that process), the two models
alternating, and the best of ``--repeats`` is kept (the least disturbed by other work).

    python benchmarks/bench_synth.py [--scale 0.05] [--repeats 3] [--old old_synth.py]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

CHILD = """
import importlib.util, json, resource, sys, time
path, scale = sys.argv[1], float(sys.argv[2])
if path:
    spec = importlib.util.spec_from_file_location("old_synth", path)
    synth = sys.modules["old_synth"] = importlib.util.module_from_spec(spec)  # for dataclasses
    spec.loader.exec_module(synth)
else:
    import slipbench.data.synth as synth
t0 = time.perf_counter()
rec, samples, labels = synth.generate(scale=scale, seed=0)
seconds = time.perf_counter() - t0
values = sum(a.size for a in samples.values())
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps({"model": synth.MODEL_VERSION, "s": seconds, "MiB": peak, "values": values}))
"""


def measure(path: str, scale: float) -> dict:
    """One generation in a fresh process: model version, seconds, peak MiB, values."""
    out = subprocess.run(
        [sys.executable, "-c", CHILD, path, str(scale)], capture_output=True, text=True
    )
    if out.returncode:
        raise SystemExit(f"generating with {path or 'this model'} failed:\n{out.stderr}")
    return json.loads(out.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scale", type=float, default=0.05)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--old", default="", help="an earlier model's synth.py")
    args = parser.parse_args()
    models = ([args.old] if args.old else []) + [""]
    runs: dict[str, list[dict]] = {m: [] for m in models}
    for _ in range(args.repeats):
        for m in models:
            runs[m].append(measure(m, args.scale))
    best = {m: min(r, key=lambda x: x["s"]) for m, r in runs.items()}
    for b in best.values():
        print(
            f"model v{b['model']} at scale {args.scale:g}: {b['s']:.2f} s (best of "
            f"{args.repeats}), peak {b['MiB']:.0f} MiB, {b['values'] / 1e6:.1f} M values"
        )
    if args.old:
        old, new = best[args.old], best[""]
        print(
            f"this / earlier: time {new['s'] / old['s']:.2f}, peak memory {new['MiB'] / old['MiB']:.2f}"
        )


if __name__ == "__main__":
    main()
