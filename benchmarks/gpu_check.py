"""One short device check (issue 32): the LSTM and tcn on every device present, LSTM models in
lockstep against one after another, and the whole paper (``evaluate --detector all --protocol
all``) under a time cap; writes the results as JSON and renders docs/studies/performance.md from them.

    python benchmarks/gpu_check.py --out gpu_check.json            # measure (under 8 min)
    python benchmarks/gpu_check.py --render A.json B.json docs/studies/performance.md  # a section each

Devices this machine lacks are reported absent, not failed. Every speed is wall-clock, best of
the repeats, on windows of random data; what else ran on the machine is not known to the script:
say it beside the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numba
import numpy as np


def _data(n: int, length: int, spread: float = 0.6) -> tuple[np.ndarray, np.ndarray]:
    """Balanced windows; slip windows vibrate more."""
    rng = np.random.default_rng(0)
    y = (np.arange(n) % 2).astype(np.int8)
    x = rng.normal(size=(n, length)).astype(np.float32)
    x[y == 1] *= 1 + spread
    return x, y


def _seconds(call: Callable[[], object], repeats: int = 2) -> float:
    """Best wall time of ``call`` after one warm-up (numba compiles, CUDA starts)."""
    call()
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        best = min(best, time.perf_counter() - start)
    return best


def _devices() -> dict[str, str]:
    """Each device and whether it is here ("present") or why not; "auto" (the default, which
    chooses) is always present, so that every row can set it against "cpu"."""
    try:
        import torch
    except ImportError:
        return {"cpu": "present", "cuda": "absent: torch is not installed", "auto": "present"}
    cuda = "present" if torch.cuda.is_available() else "absent: torch sees no CUDA device"
    return {"cpu": "present", "cuda": cuda, "auto": "present"}


def _named(arg: str, out: Path | None) -> str:
    return out.name if out is not None and arg == str(out) else arg


def _gpu_name(devices: dict[str, str]) -> str:
    if devices["cuda"] != "present":
        return ""
    import torch

    return str(torch.cuda.get_device_name())


def lstm_rows(scale: float, devices: dict[str, str]) -> list[dict]:
    """LSTM fits (one stage of 2 epochs, window 50) at batch 1 and 128 on each device; batch 1
    on the CPU also with one numba thread, whose speed should match (no threads at batch 1)."""
    from slipbench.detectors.lstm import LSTM

    rows = []
    for batch, n in ((1, int(4000 * scale)), (128, int(20000 * scale))):
        x, y = _data(n, 50)
        for device, here in devices.items():
            for threads in (numba.get_num_threads(), 1) if device == "cpu" and batch == 1 else (0,):
                rows.append(
                    _lstm_fit(LSTM, (x, y), device if here == "present" else here, batch, threads)
                )
    return rows


def _lstm_fit(cls: type, data: tuple, device: str, batch: int, threads: int) -> dict:
    row = {"model": "lstm", "setting": f"batch {batch}", "device": device, "threads": threads}
    if device.startswith("absent"):
        return row
    x, y = data
    if device == "cuda" and batch == 1:
        x, y = x[:400], y[:400]  # one launch per update: time fewer windows
    det = cls(batch_size=batch, learning_rates=(0.01,), max_epochs=(2,), device=device)
    default = numba.get_num_threads()
    numba.set_num_threads(threads or default)
    try:
        seconds = _seconds(lambda: det.fit(x, y, seed=0), repeats=1)
    finally:
        numba.set_num_threads(default)
    samples = len(x) * (1 - det.validation_fraction) * x.shape[1] * 2
    row = {**row, "windows": len(x), "seconds": seconds, "M samples/s": samples / seconds / 1e6}
    return {**row, "ran on": det.device_, "why": det.device_reason_}


def tcn_rows(scale: float, devices: dict[str, str]) -> list[dict]:
    """tcn fits (3 epochs, window 200) and inference on each device, on the same windows: an
    epoch trains ``windows_per_epoch`` of them and validates at most ``MAX_VALIDATION``, so a
    fit costs the same whatever their number (inference does not)."""
    x, y = _data(int(20000 * scale), 200, 0.3)
    rows = []
    for device, here in devices.items():
        rows.append(_tcn_fit(device, x, y) if here == "present" else {"device": here})
        rows[-1] = {"model": "tcn", "setting": "fit 3 epochs", **rows[-1]}
    return rows


def _tcn_fit(device: str, x: np.ndarray, y: np.ndarray) -> dict:
    from slipbench.detectors.tcn import TCN

    det = TCN(max_epochs=3, patience=10, device=device)
    fit = _seconds(lambda: det.fit(x, y, seed=0), repeats=1)
    infer = _seconds(lambda: det.predict_proba(x))
    n = len(x)
    trained = det.epochs_ * det.windows_per_epoch  # tcn's epoch: a set number of windows
    return {
        "device": device,
        "windows": n,
        "trained windows": trained,
        "seconds": fit,
        "train windows/s": trained / fit,
        "infer windows/s": n / infer,
        "ran on": det.device_,
        "why": det.device_why_,
    }


#: models trained together on a GPU: a batch-1 step is launch-bound, so throughput grows with them
LOCKSTEP_MODELS = (32, 512, 4096, 16384)


def lockstep_rows(devices: dict[str, str]) -> list[dict]:
    """32 LSTM models in lockstep (on numba's default threads, then on one: the speed-up per
    core) against the same models one after another on one core (same run)."""
    from slipbench.detectors.lstm_bench import lockstep_figures

    x, y = _data(250, 50)
    rows, default = [], numba.get_num_threads()
    for batch, threads in ((1, default), (128, default), (1, 1)):
        numba.set_num_threads(threads)
        try:
            fig = lockstep_figures(x, y, batch, seconds=5.0).iloc[0]
        finally:
            numba.set_num_threads(default)
        rows.append(
            {
                "model": "lstm, 32 models in lockstep",
                "setting": f"batch {batch}",
                "device": "cpu",
                "threads": threads,
                "M samples/s": fig["slipbench"] / 1e6,
                "one after another, M samples/s": fig["reference"] / 1e6,
                "speed-up": fig["slipbench"] / fig["reference"],
            }
        )
    for n_models in LOCKSTEP_MODELS:
        row = {"model": f"lstm, {n_models} models in lockstep", "setting": "batch 1"}
        if devices["cuda"] != "present":
            rows.append({**row, "device": devices["cuda"]})
            continue
        rows.append({**row, "device": "cuda", **_torch_lockstep(x, y, n_models)})
    return rows


def _torch_lockstep(x: np.ndarray, y: np.ndarray, n_models: int) -> dict:
    """An epoch of ``n_models`` models at batch 1 on CUDA (lstm_lockstep_torch), samples/s."""
    from slipbench.detectors import lstm_kernels, lstm_lockstep, lstm_lockstep_torch

    rng = np.random.default_rng(0)
    params = lstm_lockstep.pack([lstm_kernels.init_params(20, rng) for _ in range(n_models)])
    velocity, lanes = np.zeros_like(params), params.shape[0] * params.shape[2]
    orders = np.stack([rng.permutation(len(x)) for _ in range(lanes)])
    counts = np.where(np.arange(lanes) < n_models, len(x), 0)
    plan = (orders, counts, np.full(lanes, 1e-4, np.float32), 1, 0.125)
    seconds = _seconds(lambda: lstm_lockstep_torch.lockstep_epoch((x, y), plan, params, velocity))
    return {"M samples/s": n_models * x.size / seconds / 1e6}


def paper_row(seconds: float, jobs: int) -> dict:
    """``evaluate --detector all --protocol all`` at the default scale, capped at ``seconds``."""
    row = {"model": "all", "setting": f"evaluate, all protocols, --jobs {jobs}", "cap s": seconds}
    if seconds <= 0:
        return {**row, "device": "skipped (--paper-seconds 0)"}
    with tempfile.TemporaryDirectory() as out:
        command = ["--detector", "all", "--protocol", "all", "--jobs", str(jobs), "--out", out]
        start = time.perf_counter()
        try:
            done = subprocess.run(  # in its own folder: the results go there
                [sys.executable, "-m", "slipbench", "evaluate", *command],
                capture_output=True,
                timeout=seconds,
                cwd=out,
            )
            rc = done.returncode
        except subprocess.TimeoutExpired:
            rc = None
        seconds_run = time.perf_counter() - start
        cells = _cells_written(Path(out))
    return {**row, "device": "auto", "rc": rc, "seconds": seconds_run, "cells": cells}


def _cells_written(out: Path) -> str:
    """Cells per detector, their median training seconds and the devices that trained them."""
    import pandas as pd

    files = [f for f in out.rglob("*.parquet") if "result" in f.name]
    if not files:
        return "0"
    rows = pd.concat([pd.read_parquet(f) for f in files], ignore_index=True)
    ran = rows["fitted"].astype(str).str.extract(r'"device": "(\w+)"')[0].fillna("cpu")
    parts = [
        f"{name} {len(g)} ({g['train_s'].median():.2g} s, {'/'.join(sorted(set(ran[g.index])))})"
        for name, g in rows.groupby("detector")
    ]
    return f"{len(rows)}: " + ", ".join(parts)


def render(files: list[Path]) -> str:
    """docs/studies/performance.md from gpu_check JSON files, one section each."""
    runs = [{**json.loads(f.read_text()), "file": f.name} for f in files]
    lines = [
        "# Performance",
        "",
        "Generated by `python benchmarks/gpu_check.py --render RESULTS... docs/studies/performance.md`",
        "from the committed runs below; do not edit by hand.",
        "",
        "On a lent GPU machine (no package index): carry the project as wheels, as",
        "`shared/gpu/run.sh` does, then in one call run `python benchmarks/gpu_check.py --out",
        "$OUT/gpu_check.json` (under 8 min: the paper run is capped by `--paper-seconds`), commit",
        "the JSON under `benchmarks/results/` and render this page from it. Rows whose device",
        "reads `absent` were not measured; `lstm` batch 1 on the CPU runs with numba's default",
        "threads and with one: the two should match (batch-1 training launches no threads);",
        "threads 0 is numba's default. `auto` rows say where the default trained (`ran on`) and",
        "why; their figures compare with the row of that device at the same windows.",
        "",
    ]
    for results in runs:
        lines += _run_section(results)
    lines += [
        "## lockstep in the engine",
        "",
        '--8<-- "benchmarks/results/lockstep_engine.md"',
        "",
        "## lockstep on the CPU, run again",
        "",
        '--8<-- "benchmarks/results/lockstep_cpu_repeats.md"',
        "",
        "## Many models in lockstep on a GPU",
        "",
        '--8<-- "benchmarks/results/lockstep_h200.md"',
        "",
        "## The whole paper on two cores",
        "",
        '--8<-- "benchmarks/results/whole_paper_2cores.md"',
        "",
        "## The whole paper on a 16-core GPU machine",
        "",
        '--8<-- "benchmarks/results/whole_paper_h200.md"',
        "",
        "## What a run will cost",
        "",
        "`evaluate` and `run` with several detectors or protocols print, before the first cell,",
        "per detector the cells cached (and skipped) and the cells and models to run, and an",
        "estimate: models x the median seconds of a fit + cells x the median seconds of a test,",
        "both from that detector's rows already in the results folder (any run, any scale), or",
        '"no estimate yet" for a detector never measured there; the total divides the work by',
        "`--jobs`. A model trained in a lockstep batch counts the batch's time divided among its",
        "models, so a store of such rows estimates a run with batches. `--quiet` leaves it out.",
        "",
    ]
    return "\n".join(lines)


def _run_section(results: dict) -> list[str]:
    lines = [
        f"## `{results['file']}`",
        "",
        f"Written by `{results['command']}`. Load average (1, 5, 15 min) at start "
        f"{_loads(results['load average at start'])}, at end "
        f"{_loads(results['load average at end'])}. Machine: {results['machine']}; "
        f"{results['cpus']} CPUs; numba threads {results['numba threads']}; devices: "
        + ", ".join(f"{k} {v}" for k, v in results["devices"].items())
        + (f"; GPU {results['gpu']}" if results.get("gpu") else "")
        + ".",
        "",
    ]
    lines += [f"Corrected after the run: {c}.\n" for c in results.get("corrections", [])]
    for section in ("lstm", "lockstep", "tcn", "paper"):
        rows = results[section]
        keys = list(dict.fromkeys(k for r in rows for k in r))
        lines += [f"### {section}", "", "| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
        lines += ["| " + " | ".join(_cell(r.get(k, "")) for k in keys) + " |" for r in rows]
        lines.append("")
    return lines


def _loads(loads: list[float]) -> str:
    return ", ".join(f"{v:.1f}" for v in loads)


def _cell(value: object) -> str:
    return f"{value:.3g}" if isinstance(value, float) else str(value)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, help="write the results here (JSON)")
    parser.add_argument("--scale", type=float, default=1.0, help="windows per figure, relative")
    parser.add_argument("--paper-seconds", type=float, default=240.0, help="cap on the paper run")
    parser.add_argument("--jobs", type=int, default=16)
    parser.add_argument("--render", nargs="+", type=Path, metavar="RESULTS... DOC")
    args = parser.parse_args()
    if args.render:
        *files, doc = args.render
        doc.write_text(render(files) + "\n")
        return
    devices = _devices()
    results = {
        # the output named by its file alone: a machine's own folders stay out of the record
        "command": " ".join(
            ["python benchmarks/gpu_check.py", *(_named(a, args.out) for a in sys.argv[1:])]
        ),
        "load average at start": os.getloadavg(),
        "machine": platform.processor() or platform.machine(),
        "cpus": len(os.sched_getaffinity(0)),
        "numba threads": numba.get_num_threads(),
        "devices": devices,
        "gpu": _gpu_name(devices),
    }
    for name, rows in (
        ("lstm", lambda: lstm_rows(args.scale, devices)),
        ("lockstep", lambda: lockstep_rows(devices)),
        ("tcn", lambda: tcn_rows(args.scale, devices)),
        ("paper", lambda: [paper_row(args.paper_seconds, args.jobs)]),
    ):
        results[name] = rows()
        print(name, json.dumps(results[name], default=str), flush=True)
    results["load average at end"] = os.getloadavg()
    if args.out:
        args.out.write_text(json.dumps(results, indent=1, default=str) + "\n")


if __name__ == "__main__":
    main()
