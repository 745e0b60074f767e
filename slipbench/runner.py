"""The one loop: protocol cells -> windows -> fit/predict -> metrics -> result rows."""

from __future__ import annotations

import json
import platform
import sys
import threading
import time
import traceback
import zlib
from collections.abc import Iterable
from dataclasses import dataclass
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
from .results import ResultsStore, cell_key
from .signals import Signals, Windows, balance, split


def _concat(parts: list[Windows]) -> Windows:
    return Windows(
        np.concatenate([p.x for p in parts]), np.concatenate([p.recording for p in parts]),
        np.concatenate([p.index for p in parts]), parts[0].recordings,
    )


def _where(windows: Windows, conditions) -> Windows:
    mask = np.ones(len(windows), bool)
    for column, op, value in conditions:
        values = windows.column(column)
        equal = pd.Series(values).eq(value).to_numpy()
        mask &= equal if op == "==" else ~equal
    return windows.take(np.flatnonzero(mask))


class CellData:
    """Balanced, split windows per (sensor, window, downsampling), computed once and shared by
    every cell that needs them. Balancing and splitting draw from the run's seed."""

    def __init__(self, signals: Signals, how: str, seed: int):
        self.signals, self.how, self.seed = signals, how, seed
        self._cache: dict[tuple, tuple[Windows, Windows]] = {}
        rec = signals.recordings
        self._rows = {k: np.flatnonzero((rec["sensor_type"] == k[0]) & (rec["sensor_instance"] == k[1])) for k in
                      rec[["sensor_type", "sensor_instance"]].drop_duplicates().itertuples(index=False, name=None)}

    def sides(self, sensor: tuple[str, str], window: int, downsample: int) -> tuple[Windows, Windows]:
        key = (sensor, window, downsample)
        if key not in self._cache:
            self._cache[key] = self._prepare(sensor, window, downsample)
        return self._cache[key]

    def _prepare(self, sensor, window, downsample):
        name = f"{sensor[0]} {sensor[1]}"
        if sensor not in self._rows:
            raise UsageError(f"the dataset has no recordings of sensor {name}")
        rows = self._rows[sensor]
        windows = self.signals.windows(window, rows)
        if len(windows) == 0:
            longest = int(np.max(np.diff(self.signals.offsets)[rows]))
            raise UsageError(f"window {window} is longer than every recording of {name} (longest signal: {longest} samples)")
        words = [zlib.crc32(f"{sensor}|{window}".encode())]
        rng = np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=words))
        windows = windows.take(balance(windows, rng))
        if downsample > 1:
            windows = windows.downsample(downsample)
        train, test = split(windows, self.how, self.seed)
        for side, rows_ in (("train", train), ("test", test)):
            classes = set(np.unique(windows.y[rows_]))
            if classes != {0, 1}:
                missing = "slip" if 1 not in classes else "non-slip"
                raise UsageError(f"the {self.how} split of {name} at window {window} leaves no {missing} windows on the {side} side")
        return windows.take(train), windows.take(test)

    def part(self, part: Part, window: int, downsample: int) -> Windows:
        side = 0 if part.side == "train" else 1
        pooled = _concat([self.sides(s, window, downsample)[side] for s in part.sensors])
        return _where(pooled, part.where)

    def sampling_rate(self, part: Part, downsample: int) -> float:
        rec = self.signals.recordings
        rates = rec.loc[np.concatenate([self._rows[s] for s in part.sensors]), "sampling_rate_hz"].unique()
        if len(rates) > 1:
            raise UsageError(f"cell pools sensors with different sampling rates: {sorted(rates)}")
        return float(rates[0]) / downsample


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


def environment() -> dict[str, str]:
    versions = {"slipbench_version": __version__, "python_version": platform.python_version(), "numpy_version": np.__version__}
    torch = sys.modules.get("torch")
    versions["torch_version"] = getattr(torch, "__version__", "")
    versions["platform"] = platform.platform()
    return versions


@dataclass
class Run:
    """Everything that determines a run's outcome, besides the dataset's content."""

    detector: BaseDetector
    detector_name: str
    protocol: BaseProtocol
    protocol_name: str
    split: str = "paper"
    seed: int = 0

    def key(self, cell: Cell, fingerprint: str) -> str:
        return cell_key({
            "dataset": fingerprint, "detector": self.detector_name, "params": self.detector.get_params(),
            "protocol": self.protocol_name, "cell": cell.key, "train": cell.train, "test": cell.test,
            "window": cell.window, "downsample": cell.downsample, "split": self.split, "seed": self.seed,
            "version": __version__,
        })


def run_cell(run: Run, cell: Cell, data: CellData) -> tuple[dict[str, Any], pd.DataFrame | None]:
    """Fit and test one cell. Returns its result fields and its test predictions."""
    train = data.part(cell.train, cell.window, cell.downsample)
    test = data.part(cell.test, cell.window, cell.downsample)
    for side, windows in (("train", train), ("test", test)):
        classes = set(np.unique(windows.y))
        if classes != {0, 1}:
            missing = " and ".join(n for c, n in ((1, "slip"), (0, "non-slip")) if c not in classes)
            return {"status": "skipped", "reason": f"no {missing} windows to {side} on"}, None
    detector = clone(run.detector)
    rate = data.sampling_rate(cell.train, cell.downsample)
    try:
        with PeakMemory() as mem:
            t0 = time.perf_counter()
            detector.fit(train.x, train.y, sampling_rate=rate, seed=run.seed)
            t1 = time.perf_counter()
            scores = detector.predict_proba(test.x)
            t2 = time.perf_counter()
    except UsageError:
        raise
    except Exception as exc:  # a failing plugin is reported; the rest of the run goes on
        detail = "".join(traceback.format_exception_only(type(exc), exc)).strip()
        return {"status": "failed", "reason": f"detector {run.detector_name!r} raised: {detail}"}, None
    y_pred = (scores >= 0.5).astype(np.int8)
    figures = classification_figures(test.y, y_pred, test.recording, run.seed, scores=scores)
    fields = {
        "status": "ok", "reason": "",
        "n_train": len(train), "n_test": len(test), "n_test_recordings": int(len(np.unique(test.recording))),
        "sampling_rate_hz": rate, **figures,
        "train_s": t1 - t0, "train_us_per_sample": (t1 - t0) / train.x.size * 1e6,
        "infer_us_per_window": (t2 - t1) / len(test) * 1e6, "peak_mem_mb": mem.mb,
    }
    predictions = pd.DataFrame({
        "recording_id": test.recordings["recording_id"].to_numpy()[test.recording],
        "window_index": test.index, "y_true": test.y, "score": scores,
    })
    return fields, predictions


def evaluate(
    dataset: Dataset, run: Run, store: ResultsStore, *, force: bool = False, progress: bool = True,
) -> pd.DataFrame:
    """Run every cell of ``run.protocol`` with ``run.detector``; finished cells already in
    ``store`` are reused unless ``force``. Returns this run's rows."""
    cells: list[Cell] = list(run.protocol.cells(dataset.recordings))
    if not cells:
        raise UsageError(f"protocol {run.protocol_name!r} has no cells on this dataset")
    data = CellData(Signals.from_dataset(dataset), run.split, run.seed)
    # Prepare every cell's windows before training anything: a data problem stops the run
    # before it writes a single result.
    for cell in cells:
        for part in (cell.train, cell.test):
            for sensor in part.sensors:
                data.sides(sensor, cell.window, cell.downsample)
    env = environment()
    run_id = datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%S%fZ")
    rows = []
    for cell in _progress(cells, progress, f"{run.detector_name} x {run.protocol_name}"):
        key = run.key(cell, dataset.fingerprint)
        if not force and store.has(key):
            cached = store.get(key)
            if cached["status"] in ("ok", "skipped"):
                rows.append(cached)
                continue
        started = datetime.now(timezone.utc).isoformat()
        fields, predictions = run_cell(run, cell, data)
        row = {
            "key": key, "run_id": run_id, "protocol": run.protocol_name, "detector": run.detector_name,
            "detector_params": json.dumps(run.detector.get_params(), sort_keys=True, default=str),
            "split": run.split, "seed": run.seed, **cell.key, "window": cell.window, "downsample": cell.downsample,
            "cell": json.dumps(cell.key, sort_keys=True, default=str),
            "train_sensors": json.dumps(cell.train.sensors), "train_where": json.dumps(cell.train.where),
            "test_sensors": json.dumps(cell.test.sensors), "test_where": json.dumps(cell.test.where),
            **fields, "dataset_fingerprint": dataset.fingerprint,
            "dataset_path": str(dataset.path or ""), **env, "started_at": started,
            "finished_at": datetime.now(timezone.utc).isoformat(),
        }
        store.put(row, predictions)
        rows.append(row)
    store.consolidate()
    return pd.DataFrame(rows)


def _progress(items: list, enabled: bool, desc: str) -> Iterable:
    if not enabled:
        return items
    from tqdm import tqdm

    return tqdm(items, desc=desc, unit="cell", file=sys.stderr)
