"""What the engine trains in lockstep in the LSTM's part of the paper: its batches, no model trained.

    python benchmarks/lockstep_batches.py [--jobs 2] [--scale 0.05] [--out FILE]

Plans ``slipbench evaluate --detector lstm --protocol all --jobs 2`` on the default dataset (an
empty results folder: every cell to compute) and cuts its tasks into lockstep batches as
``runner.evaluate`` does (``plan.batched``), then prints, per lockstep key (rate, decimation,
window length in samples), how many models train and in which batches. A batch is one
``fit_lockstep`` call in one worker; its models step through their windows in the SIMD lanes
together (8 lanes a block, ``lstm_lockstep``), so a batch of 8 fills a block.

What it answers (issue 55): the engine already batches the LSTM's models across the whole run,
every cell of every protocol (and repeat) whose models share a key, not per cell; the share of
lanes that train a model is the room left for batching more. Cells of other window lengths
cannot join a call: the kernel steps every lane of a block through the same number of samples.
"""

from __future__ import annotations

import argparse
import collections
from pathlib import Path

from slipbench.data.defaults import default_dataset
from slipbench.detectors.lstm_lockstep import MODELS as LANES  # models a block steps at once
from slipbench.engine import registry
from slipbench.engine.plan import Batch, Run, _lockstep_key, batched
from slipbench.engine.runner import _signals, planned


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--scale", type=float, default=0.05)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    ds = default_dataset(args.scale, 0)
    lstm = registry.detectors.get("lstm")
    runs = [Run(lstm(), registry.protocols.get(p)()) for p in registry.protocols.names()]
    plan, _, _ = planned(_signals(ds, runs), ds.recordings, ds.fingerprint, runs, {})
    tasks = batched(plan.tasks, args.jobs)
    by_key: dict[tuple, list[int]] = collections.defaultdict(list)
    for task in tasks:
        key = _lockstep_key(task.tasks[0] if isinstance(task, Batch) else task)
        assert key is not None  # the LSTM is a lockstep class
        by_key[key[2], key[3], eval(key[4])[1]].append(task.models)  # noqa: S307 (its own repr)
    models = sum(task.models for task in tasks)
    blocks = sum(-(-task.models // LANES) for task in tasks)
    lines = [
        "# The LSTM's part of the paper: its lockstep batches\n",
        f"`python benchmarks/lockstep_batches.py --jobs {args.jobs} --scale {args.scale:g}`: "
        f"`slipbench evaluate --detector lstm --protocol all --jobs {args.jobs}` planned "
        f"({len(plan.cells)} cells, {models} models), cut as the engine cuts it; nothing "
        f"trained. {len(tasks)} tasks, "
        f"{sum(t.models for t in tasks if isinstance(t, Batch))} of the models in batches, "
        f"in {blocks} blocks of {LANES} lanes: {models / (blocks * LANES):.0%} of the lanes "
        "train a model.\n",
        "| rate (1/k) | decimation | window (samples) | models | batches (models each) |",
        "| --- | --- | --- | --- | --- |",
    ]
    for (rate, decimation, window), sizes in by_key.items():
        lines.append(f"| {rate} | {decimation} | {window} | {sum(sizes)} | {sizes} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        args.out.write_text(text)


if __name__ == "__main__":
    main()
