"""A bench file's calibration, measured and checked: its detectors run on many seeds and again
from another training draw on the same splits (:mod:`slipbench.gate.calibration`), the noise
written beside the file; and whether a calibration on disk still holds for the file and the
code that runs it.

The calibration holds while the bench's **settings** (its dataset, split, labels, input, the
protocols with their options and their own code, the random streams' scheme) and each
detector's **parameters and own code** (:func:`slipbench.store.keys.own_code_identity`: its
module and the slipbench modules it imports, not the rest of slipbench) are those it measured.
A detector it no longer holds for is named with the reason, and the gate falls back to what the
pull request's own seeds carry.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from slipbench.app.benchspec import Benchmark
from slipbench.engine.plan import Run
from slipbench.gate.calibration import (
    TWIN_DRAW,
    Calibration,
    DetectorCalibration,
    deterministic,
    measure,
    read_calibration,
    stale_reasons,
)
from slipbench.gate.gate import DEFAULT_TOLERANCE
from slipbench.seeding import STREAM_SCHEME
from slipbench.store.keys import canonical, own_code_identity
from slipbench.store.results import ResultsStore, cells_failed

if TYPE_CHECKING:
    from slipbench.data.format import Dataset

#: seeds a calibration runs by default: 20 degrees of freedom per paired variance
DEFAULT_SEEDS = 20


def settings(bench: Benchmark, runs: list[Run]) -> dict[str, Any]:
    """What a calibration's noise depends on besides the detectors, as plain data (paths
    relative to the bench file's folder, so that another checkout of it reads the same)."""
    from slipbench.data.synth import MODEL_VERSION

    home = bench.path.resolve().parent
    if bench.dataset is None:
        seed = bench.seed if bench.data_seed is None else bench.data_seed
        dataset: dict[str, Any] = {"scale": bench.scale, "seed": seed, "model": MODEL_VERSION}
    else:
        dataset = {
            "path": _relative(bench.dataset, home),
            **({"train": _relative(bench.train, home)} if bench.train else {}),
            **({"sensor_map": list(bench.sensor_map)} if bench.sensor_map else {}),
        }
    protocols = {
        r.protocol_name: {
            "options": r.protocol.get_params(),
            "code": own_code_identity(type(r.protocol)),
        }
        for r in runs
    }
    return canonical(
        {
            "dataset": dataset,
            "split": bench.split,
            "labels": bench.labels,
            "input": bench.input,
            "streams": STREAM_SCHEME,
            "protocols": dict(sorted(protocols.items())),
        }
    )


def _relative(path: Path, home: Path) -> str:
    try:
        return path.resolve().relative_to(home).as_posix()
    except ValueError:
        return path.name  # outside the bench's folder: its name (the fingerprint is recorded)


def digest(values: dict[str, Any]) -> str:
    return hashlib.sha256(json.dumps(values, sort_keys=True).encode()).hexdigest()


def detector_identities(runs: list[Run]) -> dict[str, tuple[dict, str]]:
    """Per detector of ``runs``: its parameters and its own code identity, as now."""
    return {
        r.detector_name: (canonical(r.detector.get_params()), own_code_identity(type(r.detector)))
        for r in runs
    }


@dataclass(frozen=True)
class CalibrationStatus:
    """A bench file's calibration as it stands: ``calibration`` (None: no file), and per
    detector of the bench it does not hold for, why (``stale``)."""

    path: Path
    calibration: Calibration | None
    stale: dict[str, str] = field(default_factory=dict)

    def holds(self, detector: str) -> bool:
        return self.calibration is not None and detector not in self.stale

    def sources(self) -> list[Calibration]:
        """What a comparison takes of it (:func:`slipbench.gate.compare.compare`'s
        ``sources``): the calibration kept to the detectors it holds for; none without one."""
        cal = self.calibration
        return [] if cal is None else [cal.holding(d for d in cal.detectors if self.holds(d))]

    def lines(self) -> list[str]:
        """What a run or a plan says of it: one line per detector it does not hold for."""
        if self.calibration is None:
            return [
                f"no calibration ({self.path.name}): the gate's noise rests on each pull "
                "request's own seeds; `slipbench calibrate` measures it once"
            ]
        return [
            f"{self.path.name} is stale for {name}: {why}; the gate falls back to the pull "
            "request's own seeds until `slipbench calibrate` measures it again"
            for name, why in self.stale.items()
        ]


def status(bench: Benchmark, runs: list[Run]) -> CalibrationStatus:
    """The calibration of ``bench`` (:attr:`Benchmark.calibration_file`) checked against its settings and ``runs``' detectors
    (a file that is not a calibration is a DataError, exit 2)."""
    path = bench.calibration_file
    if not path.is_file():
        return CalibrationStatus(path, None)
    cal = read_calibration(path)
    now = digest(settings(bench, runs))
    return CalibrationStatus(path, cal, stale_reasons(cal, now, detector_identities(runs)))


def recorded_status(bench: Benchmark, key: Mapping[str, Any]) -> CalibrationStatus:
    """The calibration of ``bench`` checked against a results folder's recorded
    ``calibration_key`` (``benchmark.json``: the settings' digest and each detector's
    parameters and own code as that run had them)."""
    path = bench.calibration_file
    if not path.is_file():
        return CalibrationStatus(path, None)
    cal = read_calibration(path)
    identities = {
        str(name): (dict(d["params"]), str(d["own_code"]))
        for name, d in dict(key.get("detectors", {})).items()
    }
    return CalibrationStatus(
        path, cal, stale_reasons(cal, str(key.get("settings_digest", "")), identities)
    )


def calibration_runs(runs: list[Run], first_seed: int, seeds: int) -> list[list[Run]]:
    """The runs of a calibration of ``seeds`` seeds from ``first_seed``, one list per seed:
    each detector, input and protocol of ``runs`` (the bench's) at that seed."""
    kinds = {(r.detector_name, r.input, r.protocol_name): r for r in runs}
    return [
        [
            Run(r.detector, r.protocol, r.split, first_seed + s, r.labels, r.normalize, r.input)
            for r in kinds.values()
        ]
        for s in range(seeds)
    ]


def calibrate(  # noqa: PLR0913 - what a calibration needs, named
    bench: Benchmark,
    runs: list[Run],
    ds: Dataset,
    seeds: int,
    work: Path,
    *,
    progress: bool,
    echo=print,
    side: Mapping[str, float] | None = None,
) -> Calibration:
    """Run ``runs``' detectors and protocols on ``ds`` (the bench's dataset) at ``seeds``
    seeds from the bench's first (in batches of its ``repeats``, as a side of a comparison
    runs them), and each again from another training draw; measure their noise and write it
    beside the bench file.

    ``work`` keeps both runs' results: an interrupted calibration resumes from them. Cells
    that fail leave no calibration written (CellsFailed, exit 4). ``side``: the start and the
    dataset's read as the caller measured them (:func:`measured_read`); the reports of the
    first seeds' rows are written into ``work``/runs and timed here, so that a side's cost
    counts everything a `slipbench run` of the file does, not its models alone."""
    per_seed = calibration_runs(runs, bench.seed, seeds)
    stores = {"runs": ResultsStore(work / "runs"), "twins": ResultsStore(work / "twins")}
    rows: dict[str, list[pd.DataFrame]] = {"runs": [], "twins": []}
    walls, load_before = [], os.getloadavg()
    measured = dict(side or {})
    size = max(1, bench.repeats)
    for lo in range(0, seeds, size):
        batch = [r for group in per_seed[lo : lo + size] for r in group]
        for kind, store in stores.items():
            todo = batch if kind == "runs" else [r.retrained(TWIN_DRAW) for r in batch]
            cached = set(store.finished())
            t0 = time.perf_counter()
            got = _evaluated(ds, todo, store, bench, progress)
            if kind == "runs" and cached.isdisjoint(got["key"]):
                walls.append((time.perf_counter() - t0) / len(per_seed[lo : lo + size]))
            if kind == "runs" and lo == 0:  # a side's rows: its reports timed as a run writes them
                measured["reports_s"] = _reports_seconds(bench, got, work / "runs")
                measured["report_seeds"] = float(len(per_seed[:size]))
            rows[kind].append(got)
        echo(f"calibration: seeds {bench.seed} to {bench.seed + min(lo + size, seeds) - 1} done")
    both = {kind: pd.concat(frames, ignore_index=True) for kind, frames in rows.items()}
    failed = cells_failed(pd.concat(both.values(), ignore_index=True), str(work))
    if failed:
        raise failed
    figures = list(bench.gate or DEFAULT_TOLERANCE)
    noise = measure(both["runs"], both["twins"], figures)
    current = settings(bench, runs)
    cal = Calibration(
        settings=current,
        digest=digest(current),
        seeds=tuple(range(bench.seed, bench.seed + seeds)),
        dataset_fingerprint=ds.fingerprint,
        created=datetime.now(timezone.utc).isoformat(timespec="seconds"),
        slipbench_version=_version(),
        wall_seconds_per_seed=float(np.median(walls)) if walls else float("nan"),
        machine={
            "processors": os.cpu_count(),
            "jobs": bench.jobs,
            "load_average": [round(load_before[0], 2), round(os.getloadavg()[0], 2)],
            "platform": platform.platform(terse=True),
        },
        detectors={
            name: DetectorCalibration(
                params=params,
                code=code,
                deterministic=deterministic(
                    _of(both["runs"], name), _of(both["twins"], name), figures
                ),
                seconds_per_seed=_work_per_seed(_of(both["runs"], name)),
                protocols=noise.get(name, {}),
            )
            for name, (params, code) in detector_identities(runs).items()
        },
        side=measured,
    )
    from slipbench.atomic import write_text_atomic

    write_text_atomic(bench.calibration_file, cal.to_json())
    return cal


def _reports_seconds(bench: Benchmark, rows: pd.DataFrame, out: Path) -> float:
    """Seconds to write the bench's reports of ``rows`` into ``out``, as a run writes them."""
    from slipbench.app.benchside import write_reports

    t0 = time.perf_counter()
    write_reports(bench, rows, out)
    return time.perf_counter() - t0


def measured_read(bench: Benchmark, echo=print) -> tuple[Dataset, dict[str, float]]:
    """The bench's dataset and what a side spends before it (``start_s``: this process's start,
    imports and planning, up to now; ``read_s``: reading the dataset). A simulated dataset not
    yet cached is simulated first (``simulate_s``: its seconds, less a read) and then read
    again, timed: a side reads it from the cache."""
    import psutil

    from slipbench.app.benchside import bench_dataset
    from slipbench.data.defaults import default_dataset_path

    start_s = time.time() - psutil.Process().create_time()
    data_seed = bench.seed if bench.data_seed is None else bench.data_seed
    cached = bench.dataset is not None or default_dataset_path(bench.scale, data_seed).is_dir()
    t0 = time.perf_counter()
    ds = bench_dataset(bench, echo)
    took = {"start_s": start_s, "read_s": time.perf_counter() - t0}
    if not cached:
        t0 = time.perf_counter()
        ds = bench_dataset(bench, echo)
        took["read_s"], made = time.perf_counter() - t0, took["read_s"]
        took["simulate_s"] = max(made - took["read_s"], 0.0)
    return ds, took


def _of(rows: pd.DataFrame, detector: str) -> pd.DataFrame:
    return rows[rows["detector"] == detector]


def _evaluated(ds, runs: list[Run], store: ResultsStore, bench: Benchmark, progress: bool):
    from slipbench.engine.runner import evaluate

    return evaluate(
        ds,
        runs,
        store,
        jobs=bench.jobs,
        scheduler=bench.scheduler,
        cell_timeout=bench.cell_timeout,
        progress=progress,
    )


def _work_per_seed(rows: pd.DataFrame) -> float:
    """Seconds of fitting (once per model) and testing (per cell) per seed, from the rows."""
    ok = rows[rows["status"] == "ok"]
    if ok.empty:
        return float("nan")
    fits = ok.drop_duplicates(["seed", "model_key"])["train_s"].astype(float).sum()
    tests = (ok["infer_us_per_window"].astype(float) * ok["n_test"].astype(float) / 1e6).sum()
    return float((fits + tests) / ok["seed"].nunique())


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("slipbench")
    except PackageNotFoundError:
        return "unknown"
