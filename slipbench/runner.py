"""The one loop: protocol cells -> windows -> fit/predict -> metrics -> result rows.

Cells that train on exactly the same windows share one model: they are grouped into a task
that fits once and tests every cell of the group. Tasks run in this process, in a local process
pool (``jobs``) or on a dask.distributed cluster (``scheduler``); the parent alone writes the
results store, one cell at a time, atomically.
"""

from __future__ import annotations

import json
import os
import platform
import sys
import threading
import time
import traceback
import zlib
from pathlib import Path
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import Any

import numpy as np
import pandas as pd
import psutil

from . import __version__
from .base import BaseDetector, BaseProtocol, Cell, Part, clone
from .data import Dataset
from .errors import UsageError
from .metrics import classification_figures
from .results import ResultsStore, cell_key, write_text_atomic
from .signals import Signals, Windows, balance, split


# ----------------------------------------------------------------------------- data per cell
def _concat(parts: list[Windows]) -> Windows:
    return Windows(None, np.concatenate([p.recording for p in parts]), np.concatenate([p.index for p in parts]), parts[0].recordings)


def _where(windows: Windows, conditions) -> Windows:
    mask = np.ones(len(windows), bool)
    for column, op, value in conditions:
        equal = pd.Series(windows.column(column)).eq(value).to_numpy()
        mask &= equal if op == "==" else ~equal
    return windows.take(np.flatnonzero(mask))


class CellData:
    """Balanced, split windows per (sensor, window), computed once and shared by every cell that
    needs them. Balancing and splitting draw from the run's seed. Only positions are kept; a
    part's samples are cut when a model needs them, so memory holds one task's windows at a
    time. The same windows serve every downsampling, as the paper downsamples its 200-sample set."""

    def __init__(self, signals: Signals, how: str, seed: int):
        self.signals, self.how, self.seed = signals, how, seed
        self._cache: dict[tuple, tuple[Windows, Windows]] = {}
        self._antialiased: dict[int, Signals] = {}
        rec = signals.recordings
        self._rows = {
            k: np.flatnonzero((rec["sensor_type"] == k[0]) & (rec["sensor_instance"] == k[1]))
            for k in rec[["sensor_type", "sensor_instance"]].drop_duplicates().itertuples(index=False, name=None)
        }

    def sides(self, sensor: tuple[str, str], window: int) -> tuple[Windows, Windows]:
        """Train and test windows (positions only) of one sensor."""
        key = (sensor, window)
        if key not in self._cache:
            self._cache[key] = self._prepare(*key)
        return self._cache[key]

    def _prepare(self, sensor, window):
        name = f"{sensor[0]} {sensor[1]}"
        if sensor not in self._rows:
            raise UsageError(f"the dataset has no recordings of sensor {name}")
        rows = self._rows[sensor]
        windows = self.signals.windows(window, rows, values=False)
        if len(windows) == 0:
            longest = int(np.max(np.diff(self.signals.offsets)[rows]))
            raise UsageError(f"window {window} is longer than every recording of {name} (longest signal: {longest} samples)")
        words = [zlib.crc32(f"{sensor}|{window}".encode())]
        windows = windows.take(balance(windows, np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=words))))
        train, test = split(windows, self.how, self.seed)
        for side, idx in (("train", train), ("test", test)):
            classes = set(np.unique(windows.y[idx]))
            if classes != {0, 1}:
                missing = "slip" if 1 not in classes else "non-slip"
                raise UsageError(f"the {self.how} split of {name} at window {window} leaves no {missing} windows on the {side} side")
        return windows.take(train), windows.take(test)

    def part(self, part: Part, window: int, downsample: int = 1, decimation: str = "plain", values: bool = True) -> Windows:
        """The windows of a part; with ``values`` their samples, downsampled as asked."""
        side = 0 if part.side == "train" else 1
        chosen = _where(_concat([self.sides(s, window)[side] for s in part.sensors]), part.where)
        if not values:
            return chosen
        signals = self.signals
        if downsample > 1 and decimation == "antialias":
            if downsample not in self._antialiased:
                self._antialiased[downsample] = self.signals.antialiased(downsample)
            signals = self._antialiased[downsample]
        chosen = Windows(signals.values(chosen, window), chosen.recording, chosen.index, chosen.recordings)
        return chosen.downsample(downsample) if downsample > 1 else chosen

    def sampling_rate(self, part: Part, downsample: int) -> float:
        rec = self.signals.recordings
        rates = rec.loc[np.concatenate([self._rows[s] for s in part.sensors]), "sampling_rate_hz"].unique()
        if len(rates) > 1:
            raise UsageError(f"a cell pools sensors with different sampling rates: {sorted(rates)}")
        return float(rates[0]) / downsample


# ----------------------------------------------------------------------------- fitting
class PeakMemory:
    """Peak resident memory above the starting level while a block runs (sampled every 5 ms;
    catches torch and numpy allocations alike, unlike tracemalloc)."""

    def __enter__(self):
        self._proc = psutil.Process()
        self._base = self._peak = self._proc.memory_info().rss
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, daemon=True)
        self._thread.start()
        return self

    def _watch(self):
        while not self._stop.wait(0.005):
            self._peak = max(self._peak, self._proc.memory_info().rss)

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self._peak = max(self._peak, self._proc.memory_info().rss)
        self.mb = (self._peak - self._base) / 2**20


@dataclass
class TestSet:
    """What one cell is tested on: windows, labels and the recording of each window."""

    x: np.ndarray
    y: np.ndarray
    groups: np.ndarray


def fit_and_test(
    detector: BaseDetector, seed: int, sampling_rate: float, train_x: np.ndarray, train_y: np.ndarray,
    tests: list[TestSet], model_path: str | None = None,
) -> list[tuple[dict[str, Any], np.ndarray | None]]:
    """Fit one model, test it on each test set. Runs in a worker: takes and returns plain data.

    With ``model_path``, a model an earlier run saved there for the same training windows is
    loaded instead of refitted (its training cost is reported as measured then), and a newly
    fitted one is saved there. Returns, per test set, its result fields and its scores. A
    detector that raises yields status "failed" with the error for every test set, so the rest
    of a run goes on.
    """
    try:
        detector, cost = _trained(detector, seed, sampling_rate, train_x, train_y, model_path)
        out = []
        for test in tests:
            t0 = time.perf_counter()
            scores = detector.predict_proba(test.x)
            infer_s = time.perf_counter() - t0
            y_pred = (scores >= 0.5).astype(np.int8)
            out.append(({
                "status": "ok", "reason": "", "n_train": len(train_x), "n_test": len(test.x),
                "n_test_recordings": int(len(np.unique(test.groups))), "sampling_rate_hz": sampling_rate,
                **classification_figures(test.y, y_pred, test.groups, seed, scores=scores),
                **cost, "infer_us_per_window": infer_s / len(test.x) * 1e6,
            }, scores))
        return out
    except UsageError:
        raise
    except Exception as exc:
        detail = "".join(traceback.format_exception_only(type(exc), exc)).strip()
        return [({"status": "failed", "reason": f"detector {detector.name or type(detector).__name__!r} raised: {detail}"}, None)] * len(tests)


def _trained(detector: BaseDetector, seed: int, sampling_rate: float, train_x: np.ndarray, train_y: np.ndarray,
             model_path: str | None) -> tuple[BaseDetector, dict[str, Any]]:
    """A fitted detector and its training cost, from ``model_path`` when an earlier run left it."""
    cost_path = None if model_path is None else Path(f"{model_path}.json")
    if cost_path is not None and cost_path.is_file():
        return type(detector).load(model_path), json.loads(cost_path.read_text())
    detector = clone(detector)
    with PeakMemory() as mem:
        t0 = time.perf_counter()
        detector.fit(train_x, train_y, sampling_rate=sampling_rate, seed=seed)
        train_s = time.perf_counter() - t0
    cost = {"train_s": train_s, "train_us_per_sample": train_s / train_x.size * 1e6, "peak_mem_mb": mem.mb}
    if model_path is not None:
        try:
            detector.save(model_path)
        except UsageError:
            return detector, cost  # state that cannot be saved safely: reuse it in this run only
        write_text_atomic(cost_path, json.dumps(cost))  # written last: it marks the model complete
    return detector, cost


# ----------------------------------------------------------------------------- planning
def environment() -> dict[str, str]:
    torch = sys.modules.get("torch")
    return {
        "slipbench_version": __version__, "python_version": platform.python_version(),
        "numpy_version": np.__version__, "torch_version": getattr(torch, "__version__", ""),
        "platform": platform.platform(),
    }


@dataclass
class Run:
    """One detector on one protocol, with a split and a seed."""

    detector: BaseDetector
    detector_name: str
    protocol: BaseProtocol
    protocol_name: str
    split: str = "paper"
    seed: int = 0

    def _common(self, fingerprint: str) -> dict[str, Any]:
        return {"dataset": fingerprint, "detector": self.detector_name, "params": self.detector.get_params(),
                "split": self.split, "seed": self.seed, "version": __version__}

    def key(self, cell: Cell, fingerprint: str) -> str:
        """Content address of a cell's result."""
        return cell_key({**self._common(fingerprint), "protocol": self.protocol_name,
                         "protocol_params": self.protocol.get_params(), "cell": cell.key, "test": cell.test,
                         "model": self.model_key(cell, fingerprint)})

    def model_key(self, cell: Cell, fingerprint: str) -> str:
        """Content address of the model a cell tests: equal keys train on the same windows."""
        return cell_key({**self._common(fingerprint), "train": cell.train, "window": cell.window,
                         "downsample": cell.downsample, "decimation": cell.decimation})


@dataclass
class Task:
    """One model to fit and the cells it is tested on."""

    run: Run  # the first run: its detector, split and seed are every cell's (they share the model key)
    cell: Cell  # the first cell: its train part, window and rate define the model
    model_key: str
    cells: list[tuple[Run, str, Cell]] = field(default_factory=list)  # cells of any protocol


def _row(run: Run, key: str, model: str, cell: Cell, fields: dict, fingerprint: str, path: str, env: dict, run_id: str) -> dict:
    return {
        "key": key, "model_key": model, "run_id": run_id, "protocol": run.protocol_name,
        "protocol_params": json.dumps(run.protocol.get_params(), sort_keys=True, default=str),
        "detector": run.detector_name,
        "detector_params": json.dumps(run.detector.get_params(), sort_keys=True, default=str),
        "split": run.split, "seed": run.seed, **cell.key, "window": cell.window, "downsample": cell.downsample,
        "decimation": cell.decimation, "cell": json.dumps(cell.key, sort_keys=True, default=str),
        "train_sensors": json.dumps(cell.train.sensors), "train_where": json.dumps(cell.train.where, default=str),
        "test_sensors": json.dumps(cell.test.sensors), "test_where": json.dumps(cell.test.where, default=str),
        **fields, "dataset_fingerprint": fingerprint, "dataset_path": path, **env,
        "finished_at": datetime.now(timezone.utc).isoformat(),
    }


def _annotated(dataset: Dataset, protocols: list[BaseProtocol]) -> Signals:
    signals = Signals.from_dataset(dataset)
    for protocol in protocols:
        for name, values in protocol.columns(dataset.recordings).items():
            signals.recordings[name] = values
    return signals


# ----------------------------------------------------------------------------- executors
def _worker_init(jobs: int) -> None:
    # share the machine's cores between the workers instead of oversubscribing them
    threads = max(1, (os.cpu_count() or 1) // jobs)
    os.environ["OMP_NUM_THREADS"] = str(threads)
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(threads)


def _dask_client(address: str):
    try:
        from distributed import Client
    except ImportError:
        raise UsageError("--scheduler needs dask.distributed: pip install 'slipbench[dask]'") from None
    try:
        return Client(address, timeout="3s")
    except (OSError, TimeoutError) as exc:
        raise UsageError(f"cannot reach the dask scheduler at {address}: {exc}") from None


def _execute(tasks: list[Task], payload: Callable[[Task], tuple], jobs: int, scheduler: str | None,
             timeout: float | None) -> Iterator[tuple[Task, list | None]]:
    """Run tasks; yield each with its results (None when it hit the time limit).

    At most two tasks per worker are in flight, so their windows are not all in memory at once.
    """
    if scheduler:
        from distributed import as_completed

        client = _dask_client(scheduler)
        try:
            futures = {client.submit(fit_and_test, *payload(t), pure=False): t for t in tasks}
            for future in as_completed(futures):
                yield futures[future], future.result()
        finally:
            client.close()
        return
    if jobs <= 1 and not timeout:
        for task in tasks:
            yield task, fit_and_test(*payload(task))
        return
    from concurrent.futures import TimeoutError as FutureTimeout

    # pebble, unlike concurrent.futures, kills a worker that overruns its time limit
    from pebble import ProcessPool

    with ProcessPool(max_workers=jobs, initializer=_worker_init, initargs=(jobs,)) as pool:
        pending: list = []
        queue = iter(tasks)
        while True:
            for task in queue:
                pending.append((pool.schedule(fit_and_test, args=payload(task), timeout=timeout), task))
                if len(pending) >= 2 * jobs:
                    break
            if not pending:
                return
            future, task = pending.pop(0)
            try:
                yield task, future.result()
            except FutureTimeout:
                yield task, None


# ----------------------------------------------------------------------------- the run
def evaluate(
    dataset: Dataset,
    runs: Run | list[Run],
    store: ResultsStore,
    *,
    force: bool = False,
    jobs: int = 1,
    scheduler: str | None = None,
    cell_timeout: float | None = None,
    progress: bool = True,
) -> pd.DataFrame:
    """Run every cell of every run; finished cells already in ``store`` are reused unless
    ``force``. Returns the rows of these runs, in protocol order.

    Parameters
    ----------
    jobs : local worker processes (1: run in this process).
    scheduler : address of a dask.distributed scheduler; tasks run on its workers.
    cell_timeout : seconds one model may take to fit and test its cells in a local worker
        before they are reported with status "timeout" (runs a process pool even for 1 job).
    """
    runs = [runs] if isinstance(runs, Run) else runs
    signals = _annotated(dataset, [r.protocol for r in runs])
    datas: dict[tuple[str, int], CellData] = {}
    fingerprint, path = dataset.fingerprint, str(dataset.path or "")
    env, run_id = environment(), datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%S%fZ")

    def data_of(run: Run) -> CellData:
        if (run.split, run.seed) not in datas:
            datas[run.split, run.seed] = CellData(signals, run.split, run.seed)
        return datas[run.split, run.seed]

    def windows(run: Run, cell: Cell, part: Part, values: bool = True) -> Windows:
        return data_of(run).part(part, cell.window, cell.downsample, cell.decimation, values)

    def record(run: Run, key: str, cell: Cell, fields: dict, scores: np.ndarray | None = None) -> None:
        row = _row(run, key, run.model_key(cell, fingerprint), cell, fields, fingerprint, path, env, run_id)
        predictions = None
        if scores is not None:
            test = windows(run, cell, cell.test, values=False)
            predictions = pd.DataFrame({
                "recording_id": signals.recordings["recording_id"].to_numpy()[test.recording],
                "window_index": test.index, "y_true": test.y, "score": scores,
            })
        store.put(row, predictions)
        rows[key] = row

    # plan: every cell's windows are prepared before anything trains, so a data problem stops
    # the run before it writes a single result
    rows: dict[str, dict] = {}
    order: list[str] = []
    tasks: dict[str, Task] = {}
    stored = {} if force else store.finished()
    for run in runs:
        run.detector.validate_params()
        cells = list(run.protocol.cells(dataset.recordings))
        if not cells:
            raise UsageError(f"protocol {run.protocol_name!r} has no cells on this dataset")
        for cell in cells:
            key = run.key(cell, fingerprint)
            order.append(key)
            if stored.get(key, {}).get("status") in ("ok", "skipped"):
                rows[key] = stored[key]
                continue
            reason = cell.skip
            if not reason:
                for part, role in ((cell.train, "train"), (cell.test, "test")):
                    missing = _missing_classes(windows(run, cell, part, values=False).y)
                    if missing:
                        reason = f"no {missing} windows to {role} on"
                        break
            if reason:
                record(run, key, cell, {"status": "skipped", "reason": reason})
                continue
            model = run.model_key(cell, fingerprint)
            tasks.setdefault(model, Task(run, cell, model)).cells.append((run, key, cell))

    def payload(task: Task) -> tuple:
        run, c = task.run, task.cell
        train = windows(run, c, c.train)
        tests = [windows(run, cell, cell.test) for _, _, cell in task.cells]
        return (run.detector, run.seed, data_of(run).sampling_rate(c.train, c.downsample), train.x, train.y,
                [TestSet(t.x, t.y, t.recording) for t in tests],
                model_path(task))

    def model_path(task: Task) -> str | None:
        if scheduler:
            return None  # dask workers may not see this disk
        path = store.model_path(task.model_key)
        if force:
            Path(f"{path}.json").unlink(missing_ok=True)
        return str(path)

    detectors, protocols = dict.fromkeys(r.detector_name for r in runs), dict.fromkeys(r.protocol_name for r in runs)
    desc = " x ".join(next(iter(names)) if len(names) == 1 else f"{len(names)} {kind}"
                      for names, kind in ((detectors, "detectors"), (protocols, "protocols")))
    bar = _progress(len(order), len(rows), progress, desc)
    try:
        for task, results in _execute(list(tasks.values()), payload, jobs, scheduler, cell_timeout):
            if results is None:
                results = [({"status": "timeout", "reason": f"the model did not fit and test within {cell_timeout:g} s"}, None)] * len(task.cells)
            for (run, key, cell), (fields, scores) in zip(task.cells, results):
                record(run, key, cell, fields, scores)
            bar.update(len(task.cells))
    finally:
        bar.close()
        store.consolidate()
    return pd.DataFrame([rows[k] for k in order])


def _missing_classes(y: np.ndarray) -> str:
    classes = set(np.unique(y))
    return " and ".join(n for c, n in ((1, "slip"), (0, "non-slip")) if c not in classes)


def _progress(total: int, done: int, enabled: bool, desc: str):
    """A progress bar: cells done (cached and skipped ones count at once) and the time left."""
    from tqdm import tqdm

    bar = tqdm(total=total, initial=done, desc=desc, unit="cell", file=sys.stderr, disable=not enabled)
    bar.set_postfix_str(f"{done} cached or skipped", refresh=False)
    return bar
