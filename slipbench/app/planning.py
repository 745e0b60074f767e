"""`slipbench run FILE --plan`: what a run file will compute and cost, said before anything
runs. No cell runs and no data is generated: the simulated dataset is laid out from its design
(each recording's length, no sample; :func:`slipbench.data.synth.layout`), a dataset folder
is read as it is. Every cell is planned as the run plans it (windows, keys, models, lockstep
batches), and each model is charged with the rates measured in earlier rows
(:mod:`slipbench.engine.estimate`): the run's own results folder and the folders given with
``--measured``, at any scale.

The plan is a list of :class:`Section`; each builder of :data:`SECTIONS` reads one
:class:`Planning` and returns its section (or None where it has nothing to say), so another
section joins by adding its builder; the last says what the gate can see
(:func:`the_gate`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from slipbench.app.benchfile import plan_runs, slurm_of
from slipbench.app.benchspec import Benchmark
from slipbench.engine.estimate import Cost, costs, duration, makespan, task_seconds
from slipbench.engine.limits import limit_words
from slipbench.engine.plan import Batch, Plan, Task, batched
from slipbench.engine.slurm import Resources, array_minutes, dealt
from slipbench.vocabulary import SLIPS


@dataclass
class Section:
    """One part of the plan: a title and its lines (Markdown)."""

    title: str
    lines: list[str]


@dataclass
class Planning:
    """What the sections read: the run file, the plan of its cells on the dataset's layout
    (``data``: what it stands on), the measured rows, the run's tasks as it batches them with
    their estimated seconds (NaN: unknown), and the [slurm] resources (None: no table)."""

    bench: Benchmark
    data: str
    plan: Plan
    done: set[str]
    measured: dict[str, dict]
    tasks: list[Task | Batch]
    seconds: list[float]
    slurm: Resources | None
    took_s: float = 0.0
    costs: dict[str, Cost] = field(default_factory=dict)
    runs: list = field(default_factory=list)  # the file's runs, as plan_runs made them


def _layout(bench: Benchmark, echo: Callable[[str], None]):
    """(signals, recordings, fingerprint, a line saying what the data is) of the file's
    dataset; the simulated one laid out from its design, never simulated."""
    from slipbench.data.canonical import canonical_recordings
    from slipbench.data.defaults import cache_dir
    from slipbench.data.read import stored_fingerprint
    from slipbench.data.signals import Signals
    from slipbench.data.synth import MODEL_VERSION, layout

    if bench.dataset is not None:
        from slipbench.app.benchside import read_data

        ds = read_data(bench, echo)
        return Signals.from_dataset(ds), ds.recordings, ds.fingerprint, f"dataset {ds.path}"
    seed = bench.seed if bench.data_seed is None else bench.data_seed
    laid = layout(bench.scale, seed)
    rec = canonical_recordings(laid.drop(columns="n_samples"), "the simulated design")
    rec["n_samples"] = laid.set_index("recording_id").loc[rec["recording_id"], "n_samples"].values
    # not simulated, so not known to slip: a hold-slip trial is taken to, as the design means it
    rec[SLIPS] = rec["scenario"].isin(["slip", "hold-slip"]).to_numpy()
    folder = cache_dir() / f"synth-v{MODEL_VERSION}-scale{bench.scale:g}-seed{seed}"
    per_unit = rec.groupby(["sensor_type", "sensor_instance"])["n_samples"].sum().median()
    what = (
        f"the simulated design at scale {bench.scale:g}, seed {seed}, laid out from its design "
        f"(not simulated): {len(rec)} recordings, {per_unit / 1e6:.2g} M samples per unit"
    )
    # a simulated dataset already in the cache: its stored fingerprint finds the cells cached
    return Signals.from_layout(rec), rec, stored_fingerprint(folder), what


def planning(bench: Benchmark, measured: list[Path], echo: Callable[[str], None]) -> Planning:
    """Plan the file's run and charge its models (see the module's docstring)."""
    from slipbench.engine.runner import planned, with_columns
    from slipbench.store.results import ResultsStore

    start = time.perf_counter()
    runs = plan_runs(bench, echo)
    signals, recordings, fingerprint, data = _layout(bench, echo)
    signals = with_columns(signals, recordings, runs)
    store = ResultsStore(bench.out)
    stored = store.finished() if (bench.out / "cells").is_dir() else {}
    plan, done, _ = planned(signals, recordings, fingerprint, runs, stored)
    rows = dict(stored)
    for folder in measured:
        rows.update(ResultsStore(folder).finished())
    slurm = slurm_of(bench) or (_resources(bench) if bench.slurm else None)
    workers = (
        slurm.array_parallelism * slurm.cpus_per_task if slurm is not None else bench.jobs or 1
    )
    tasks: list[Task | Batch] = batched(plan.tasks, workers)
    p = Planning(bench, data, plan, done, rows, tasks, task_seconds(plan, rows, tasks), slurm)
    p.costs = costs(plan, done, rows)
    p.runs = runs
    p.took_s = time.perf_counter() - start
    return p


def _resources(bench: Benchmark) -> Resources:
    from slipbench.engine.slurm import resources

    return resources(bench.slurm, tuple(bench.detectors))


def cells_and_cost(p: Planning) -> Section:
    """Per detector: cells, models, and the work they should take."""
    limit = limit_words(p.bench.cell_timeout, p.bench.jobs, p.bench.scheduler)
    lines = [
        f"Data: {p.data}. Measured rows behind the estimates: {len(p.measured)}.",
        "",
        f"{limit[0].upper()}{limit[1:]}.",
        "",
        "| Detector | Cells | Cached | Skipped | To run | Models | Work (CPU) | Longest model "
        "| Measured from |",
        "|:--|--:|--:|--:|--:|--:|--:|--:|:--|",
    ]
    for name, c in p.costs.items():
        cells = c.cached + c.skipped + c.to_run
        if c.model_s:
            work, longest = duration(sum(c.model_s)), duration(max(c.model_s))
            basis = f"{c.measured} rows" + ("" if c.alike else " of other parameters")
            if c.unknown:  # e.g. streaming cells where the pilot ran none
                basis += f"; {c.unknown} models not counted (cells of a kind never measured)"
        else:
            work = longest = "-"
            basis = "nothing measured" if c.to_run else ""
        lines.append(
            f"| {name} | {cells} | {c.cached} | {c.skipped} | {c.to_run} | {c.models} | {work} "
            f"| {longest} | {basis} |"
        )
    unknown = [n for n, c in p.costs.items() if c.to_run and c.seconds is None]
    if unknown:
        lines += [
            "",
            f"No measured cell of {', '.join(unknown)}: run the file at a small scale (its "
            "[dataset] scale) into another folder first, and give it with --measured FOLDER.",
        ]
    return Section("Cells and work", lines)


def on_this_machine(p: Planning) -> Section | None:
    """The wall time with the file's local workers."""
    known = [s for s in p.seconds if np.isfinite(s)]
    if not known:
        return None
    jobs = max(p.bench.jobs, 1)
    wall = makespan(known, jobs)
    missing = len(p.seconds) - len(known)
    tail = f" (without {missing} tasks of detectors nothing measured)" if missing else ""
    return Section(
        "On this machine",
        [
            f"With {jobs} worker(s) (run.jobs): about {duration(wall)} of wall time{tail}, "
            f"{sum(known) / 3600:.1f} core-hours in models; the longest task "
            f"{duration(max(known))}. This counts the models' fits and tests only, from "
            "the measured rows; the process's start, reading the data, windowing and the "
            "reports come on top (a file with a [gate] counts them in its cost of a side, as "
            "its calibration measured them)."
        ],
    )


def on_slurm(p: Planning) -> Section | None:
    """Per detector's job array: its resources, array tasks, time limit, and what it
    should take; then the run's wall time at the stated parallelism and its core-hours."""
    res = p.slurm
    if res is None:
        return None
    seconds = {id(t): s for t, s in zip(p.tasks, p.seconds, strict=True)}
    # dealt as the run deals them: by estimated seconds, by models where nothing is measured
    shards = dealt(
        p.tasks, res, lambda t: seconds[id(t)] if np.isfinite(seconds[id(t)]) else t.models
    )
    lines = [
        "| Detector | Resources | Array tasks | Longest task | Time limit | Wall | Core-hours |",
        "|:--|:--|--:|--:|--:|--:|--:|",
    ]
    walls, core_h, notes = [], 0.0, []
    for detector in dict.fromkeys(s.detector for s in shards):
        mine = [s for s in shards if s.detector == detector]
        r = res.of(detector)
        times = [makespan([seconds[id(t)] for t in s.tasks], r.cpus_per_task) for s in mine]
        known = bool(np.isfinite(times).all())
        limit = array_minutes(r, mine, p.bench.cell_timeout)
        shown_limit = f"{limit} min" if limit else "needs time or cell_timeout"
        if known:
            wall = makespan(times, r.array_parallelism)
            walls.append(wall)
            core_h += sum(times) * r.cpus_per_task / 3600
            if limit and max(times) > limit * 60:
                notes.append(
                    f"{detector}: its longest array task should take {duration(max(times))}, "
                    f"more than its time limit of {limit} min: raise time or tasks"
                )
        lines.append(
            f"| {detector} | {r.described()} | {len(mine)} | "
            f"{duration(max(times)) if known else '-'} | {shown_limit} | "
            f"{duration(wall) if known else '-'} | "
            f"{f'{sum(times) * r.cpus_per_task / 3600:.1f}' if known else '-'} |"
        )
    total = (
        f"All arrays at once, at most {res.array_parallelism} tasks each running: about "
        f"{duration(max(walls))} of wall time and {core_h:.1f} core-hours allocated"
        if walls
        else "No estimate: nothing measured."
    )
    return Section(
        "On SLURM ([slurm])",
        [
            *lines,
            "",
            total + " (each task also reads the dataset and plans its cells before its first "
            "model; queueing not counted).",
            *(f"- {n}" for n in notes),
        ],
    )


def the_gate(p: Planning) -> Section | None:
    """What `compare --bench` can see with this file (:mod:`slipbench.app.gateplan`): per
    gated figure, protocol and detector, the smallest drop flagged with 80 % power at the
    file's seeds and at its budget, from its calibration; a file without [gate] says nothing."""
    if not p.bench.gate and p.bench.budget is None:
        return None
    from slipbench.app.calibrate import status
    from slipbench.app.gateplan import plan_gate

    lines = plan_gate(p.bench, p.runs, status(p.bench, p.runs)).lines()
    return Section("The gate ([gate])", ["```text", *lines, "```"])


#: the plan's sections, in order: a builder per section, each reading the Planning
SECTIONS: list[Callable[[Planning], Section | None]] = [
    cells_and_cost,
    on_this_machine,
    on_slurm,
    the_gate,
]


def render(p: Planning) -> str:
    """The plan as Markdown: every section that has something to say."""
    out = [f"# Plan of {p.bench.describe}", ""]
    for build in SECTIONS:
        section = build(p)
        if section is not None:
            out += [f"## {section.title}", "", *section.lines, ""]
    out.append(f"Planned in {p.took_s:.1f} s; no cell ran and no data was generated.")
    return "\n".join(out)


def frame(p: Planning) -> pd.DataFrame:
    """Per detector, the plan's figures as numbers (for tests and scripts)."""
    return pd.DataFrame(
        [
            {
                "detector": n,
                "cells": c.cached + c.skipped + c.to_run,
                "cached": c.cached,
                "skipped": c.skipped,
                "to_run": c.to_run,
                "models": c.models,
                "seconds": c.seconds,
            }
            for n, c in p.costs.items()
        ]
    )
