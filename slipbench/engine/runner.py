"""A run, from planning to stored rows: plan the cells, execute the tasks, record each cell.

``evaluate`` is the one loop: protocol cells -> windows -> fit/predict -> metrics -> rows.
Planning (:mod:`slipbench.engine.plan`) computes every cell's windows and keys once; an executor
(:mod:`slipbench.engine.executors`) fits the models; this module writes each finished cell to the
results store, atomically, in the parent process alone.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.metadata
import json
import os
import pickle
import platform
import sys
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np
import pandas as pd

from slipbench import __version__
from slipbench.data.format import Dataset
from slipbench.data.read import read_dataset, stored_fingerprint
from slipbench.data.signals import Signals, channel_scales, standardized
from slipbench.engine.cached import refits, reusable
from slipbench.engine.estimate import costs, describe
from slipbench.engine.executors import Executor, workers_for
from slipbench.engine.fitting import NOTICES, Job, Lockstep, Result, Stored, TestSet
from slipbench.engine.limits import SCHEDULERS
from slipbench.engine.plan import (
    LABELLED,
    Batch,
    Plan,
    PlannedCell,
    Run,
    Task,
    batched,
    check_labels,
    make_plan,
    run_code_identity,
)
from slipbench.errors import DataError, EnvironmentFault, UsageError
from slipbench.protocol import Cell, described
from slipbench.stats.bootstrap import DEFAULT_METHOD
from slipbench.store.columns import checked
from slipbench.store.keys import canonical
from slipbench.store.results import ResultsStore
from slipbench.stream.cell import Recordings, StreamTest

if TYPE_CHECKING:
    from typing_extensions import Unpack

    from slipbench.engine.slurm import Resources


def _version_of(distribution: str) -> str:
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return ""


def environment() -> dict[str, str]:
    torch = sys.modules.get("torch")
    return {
        "slipbench_version": __version__,
        # the intervals' method: stored cells keep theirs when the default changes
        "interval_method": DEFAULT_METHOD,
        "python_version": platform.python_version(),
        "numpy_version": np.__version__,
        # the LSTM's kernels are compiled with fastmath: another numba (LLVM) trains them to
        # other weights, several points apart at long windows
        "numba_version": _version_of("numba"),
        "torch_version": getattr(torch, "__version__", ""),
        "platform": platform.platform(),
    }


@dataclass(frozen=True)
class Stamp:
    """What every row of one run records about where it comes from: the run's id, the dataset
    (fingerprint, path and, for a combined dataset, ``origin``: the datasets it was built from,
    see :func:`slipbench.data.transfer.combine`) and the environment."""

    run_id: str
    fingerprint: str
    path: str
    origin: dict
    env: dict


def _row(pc: PlannedCell, fields: dict, stamp: Stamp) -> dict:
    """One result row, through the results schema (:mod:`slipbench.store.columns`)."""
    run, cell = pc.run, pc.cell
    return checked(
        {
            "key": pc.key,
            "model_key": pc.model_key,
            "run_id": stamp.run_id,
            "protocol": run.protocol_name,
            "protocol_params": _json(run.protocol.get_params()),
            **described(run.protocol),
            "detector": run.detector_name,
            "detector_params": _json(run.detector.get_params()),
            "detector_reference": bool(run.detector.reference),
            "split": run.split,
            "seed": run.seed,
            "labels": run.labels,
            "normalize": run.normalize,
            "input": run.input,
            "balance": run.balance,
            "code_identity": run_code_identity(run),
            **cell.key,
            "window": cell.window,
            "downsample": cell.downsample,
            "decimation": cell.decimation,
            "antialias": cell.antialias,
            "cell": cell.name,
            "train_sensors": _json(cell.train.sensors),
            "train_where": _json(cell.train.where),
            "test_sensors": _json(cell.test.sensors),
            "test_where": _json(cell.test.where),
            # with the model key, what the cell is scored on (the leaderboard merges cells alike)
            "test_stream": _json(cell.stream) if cell.stream else "",
            **window_counts(pc),
            **fields,
            "dataset_fingerprint": stamp.fingerprint,
            "dataset_path": stamp.path,
            **stamp.origin,
            **stamp.env,
            "finished_at": datetime.now(timezone.utc).isoformat(),
        }
    )


def window_counts(pc: PlannedCell) -> dict[str, int | str]:
    """Windows per class on each side after balancing and splitting (``train_slip_windows``,
    ``train_nonslip_windows``, ``test_slip_windows``, ``test_nonslip_windows``), where the cell
    got that far (a streaming cell tests on recordings, not windows: train counts only); those
    each side could hold before balancing (``train_slip_available``, ...) and the cell's
    ``balance_warning`` where balancing kept under half of a class."""
    out: dict[str, int | str] = {}
    for role, windows in (("train", pc.train), ("test", pc.test)):
        if windows is not None:
            out[f"{role}_slip_windows"] = int((windows.y == 1).sum())
            out[f"{role}_nonslip_windows"] = int((windows.y == 0).sum())
    return out | pc.available | {"balance_warning": pc.balance_warning}


def _json(value) -> str:
    """Plain JSON of a parameter dict, key or filter, as stored in result rows."""
    return json.dumps(canonical(value), sort_keys=True)


def _signals(dataset: Dataset, runs: list[Run]) -> Signals:
    return with_columns(Signals.from_dataset(dataset), dataset.recordings, runs)


def with_columns(signals: Signals, recordings: pd.DataFrame, runs: list[Run]) -> Signals:
    """``signals`` whose recordings carry :data:`LABELLED` and the columns the runs' protocols
    add (:meth:`BaseProtocol.columns` of ``recordings``)."""
    signals.recordings[LABELLED] = signals.labelled
    for run in runs:
        for name, values in run.protocol.columns(recordings).items():
            signals.recordings[name] = values
    return signals


def planned(
    signals: Signals,
    recordings: pd.DataFrame,
    fingerprint: str,
    runs: list[Run],
    stored: dict[str, dict],
) -> tuple[Plan, set[str], set[str]]:
    """What a run of ``runs`` computes, computing nothing: the plan of every cell (the
    protocols' cells of ``recordings``), the keys of ``stored`` rows it reuses (ok or skipped,
    unless their fit read a file changed since) and those model keys that fit again."""
    with_cells = [(run, run.cells_or_stand_in(recordings)) for run in runs]
    refit = refits(stored)  # model keys whose fits read a file that has changed since
    done = reusable(stored, refit)
    return make_plan(signals, with_cells, fingerprint, done), done, refit


class Options(TypedDict, total=False):
    """How :func:`evaluate` runs its cells (every key optional; see there)."""

    force: bool
    jobs: int
    scheduler: str | None
    cell_timeout: float | None
    progress: bool
    lockstep: bool
    slurm: Resources | None


def evaluate(
    dataset: Dataset, runs: Run | list[Run], store: ResultsStore, **options: Unpack[Options]
) -> pd.DataFrame:
    """Run every cell of every run; finished cells already in ``store`` are reused unless
    ``force``. Returns the rows of these runs, in protocol order.

    Options
    -------
    force : compute every cell again (default False).
    jobs : local worker processes, 1 by default (0: in this process, for debugging: a crash
        there ends the run).
        Called from a script without an ``if __name__ == "__main__":`` guard, ``jobs=1`` runs
        in this process (workers would import the script again) and more jobs or a
        ``cell_timeout`` are refused with a UsageError saying to add the guard.
    scheduler : address of a dask.distributed scheduler; tasks run on its workers. Or
        ``"slurm"``: a SLURM job array through submitit, whose tasks write their cells into
        ``store`` (a folder the nodes share); ``"submitit-local"``: the same through local
        processes (:mod:`slipbench.engine.slurm`).
    cell_timeout : seconds one model may take to fit and test its cells in a local worker
        (or in an array task, whose time limit follows from it) before they are reported
        with status "timeout".
    slurm : the array tasks' resources (:class:`slipbench.engine.slurm.Resources`; default:
        its defaults) with ``scheduler="slurm"`` or ``"submitit-local"``.
    progress : a bar of the cells done on stderr, with the latest progress a model in flight
        reports (``lstm: epoch 12/30, loss 0.41``; :meth:`BaseDetector.report_progress`).
    lockstep : train the models of a lockstep class (:attr:`BaseDetector.lockstep`) that share
        its :meth:`~BaseDetector.lockstep_key` together, a batch per task (default True, or
        False where the environment variable ``SLIPBENCH_LOCKSTEP`` is ``0``); the rows are
        those of models trained one at a time.
    """
    unknown = sorted(set(options) - set(Options.__annotations__))
    if unknown:  # a misspelt option must not be ignored
        raise TypeError(f"evaluate() got unknown options: {', '.join(unknown)}")
    force, scheduler = options.get("force", False), options.get("scheduler")
    cell_timeout, progress = options.get("cell_timeout"), options.get("progress", True)
    runs = [runs] if isinstance(runs, Run) else runs
    jobs = workers_for(
        options.get("jobs", 1), scheduler, cell_timeout
    )  # before any work: a script may be refused
    for run in runs:
        run.validate()
        check_labels(run.labels, dataset)
    stored = {} if force else store.finished()
    fingerprint = dataset.fingerprint
    signals = _signals(dataset, runs)
    plan, done, refit = planned(signals, dataset.recordings, fingerprint, runs, stored)
    tasks: list[Task | Batch] = list(plan.tasks)
    if options.get("lockstep", os.environ.get("SLIPBENCH_LOCKSTEP", "1") != "0"):
        tasks = batched(plan.tasks, _parallel(jobs, scheduler, options.get("slurm")))
    run_id = datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%S%fZ")
    stamp = Stamp(run_id, fingerprint, str(dataset.path or ""), dataset.origin or {}, environment())
    rows: dict[str, dict] = {pc.key: stored[pc.key] for pc in plan.cells if pc.key in done}
    if len(rows) < len(plan.cells):  # cells to write: an unwritable folder fails before any fit
        store.check_writable()

    record = _Recorder(plan, signals, stamp, store, rows)
    for pc in plan.cells:
        if pc.key not in rows and pc.skip:
            record(pc, Result({"status": "skipped", "reason": pc.skip}))

    if scheduler is None:  # this machine's workers: a cold kernel cache compiled once, here
        _prepare(tasks, progress)
    cached = len(rows)
    if progress and len(runs) > 1:  # several detectors or protocols: say what it costs
        for line in describe(costs(plan, done, stored), jobs):
            print(line, file=sys.stderr)
    bar = _progress(len(plan.cells), cached, progress, _describe(runs))
    try:
        if force:
            refit = {pc.model_key for pc in plan.cells}
        payload = lambda task: _work(plan, task, store, refit, scheduler)  # noqa: E731
        remote = None
        if scheduler in SCHEDULERS:
            remote = _remote(dataset, stamp, store, refit, options)
        executor = Executor(jobs, scheduler, cell_timeout, options.get("slurm"))
        finished = executor.run(tasks, payload, _shown(bar, cached) if progress else None, remote)
        with contextlib.closing(finished):  # stopped at once when this loop is left early
            for task, results in finished:
                for pc, result in zip(task.cells, results, strict=True):
                    record(pc, result)
                bar.update(len(task.cells))
    except BaseException:
        bar.close()
        with contextlib.suppress(EnvironmentFault):  # the first fault is the one to report
            store.consolidate()
        raise
    bar.close()
    store.consolidate()
    return pd.DataFrame([rows[pc.key] for pc in plan.cells])


@dataclass
class _Recorder:
    """Writes each finished cell of a plan to the store (its row, with the run's stamp, and its
    test windows' scores), or takes the row an array task stored; ``rows`` collects them."""

    plan: Plan
    signals: Signals
    stamp: Stamp
    store: ResultsStore
    rows: dict[str, dict]
    warned: set[tuple[str, str]] = field(default_factory=set)

    def __call__(self, pc: PlannedCell, result: Result) -> None:
        _warn_reads(pc.run.detector_name, result.fields, self.warned)
        fields = {k: v for k, v in result.fields.items() if k != NOTICES}
        for notice in result.fields.get(NOTICES, ()):  # a task's cells share its model
            if ("", notice) not in self.warned:
                self.warned.add(("", notice))
                warnings.warn(notice, stacklevel=2)
        if isinstance(result, Stored):
            self.rows[pc.key] = fields
            return
        fields = {**fields, **_scales(self.plan, pc)}
        if pc.notes and fields.get("status") == "ok":
            fields["warnings"] = "; ".join([*pc.notes, *filter(None, [fields.get("warnings")])])
        row = _row(pc, fields, self.stamp)
        predictions = None
        if result.scores is not None:  # the scores of test windows (a streaming cell keeps none)
            rec, test = self.signals.recordings, pc.windows("test")
            predictions = pd.DataFrame(
                {
                    "recording_id": rec["recording_id"].to_numpy()[test.recording],
                    "trial": rec["trial"].to_numpy()[test.recording],
                    "window_index": test.index,
                    "y_true": test.y,
                    "score": result.scores,
                }
            )
        self.store.put(row, predictions)
        self.rows[pc.key] = row


def _parallel(jobs: int, scheduler: str | None, slurm: Resources | None) -> int:
    """Models that train at once: local workers, or a job array's tasks times their cores."""
    if scheduler not in SCHEDULERS:
        return max(jobs, 1)
    from slipbench.engine.slurm import Resources

    res = slurm or Resources()
    return res.array_parallelism * res.cpus_per_task


@dataclass
class ArrayTask:
    """What one array task of a SLURM run computes (:mod:`slipbench.engine.slurm`), as plain
    data: the dataset (a folder, or the pickle of one the launcher wrote), the runs with the
    cells of its models, each unit of work as its model keys (a lockstep batch: several,
    kept together as the launcher batched them), and where and how to write the rows."""

    dataset: str
    stamp: Stamp
    runs: list[tuple[Run, list[Cell]]]
    units: list[list[str]]
    store: str
    refit: set[str]
    workers: int
    cell_timeout: float | None
    dataset_sha256: str = ""  # of a pickled dataset: proved before it is unpickled

    def __call__(self) -> dict[str, str]:
        """Plan these cells again from the dataset, fit and test them in a local pool of
        ``workers``, write each verified cell; returns each cell's status by key."""
        path = Path(self.dataset)
        if path.suffix == ".pkl":
            dataset = _unpickled(path, self.dataset_sha256)
        else:
            dataset = read_dataset(path)
        fingerprint = self.stamp.fingerprint
        if dataset.fingerprint != fingerprint:
            raise DataError(
                f"{path}: its content changed since the run was launched (fingerprint "
                f"{dataset.fingerprint}, the launcher's {fingerprint})"
            )
        signals = _signals(dataset, [run for run, _ in self.runs])
        plan = make_plan(signals, self.runs, fingerprint, set())
        by_model = {t.model_key: t for t in plan.tasks}
        wanted = {k for unit in self.units for k in unit}
        if set(by_model) != wanted:
            raise UsageError(
                f"this array task planned {len(set(by_model) - wanted)} models its launcher did "
                f"not and lacks {len(wanted - set(by_model))} it did: the nodes must run the same "
                "slipbench, plugins and libraries as the launcher"
            )
        units: list[Task | Batch] = [
            by_model[u[0]] if len(u) == 1 else Batch([by_model[k] for k in u]) for u in self.units
        ]
        store = ResultsStore(self.store)
        stamp = replace(self.stamp, env=environment())
        record = _Recorder(plan, signals, stamp, store, {})
        payload = lambda task: _work(plan, task, store, self.refit, None)  # noqa: E731
        pool = Executor(self.workers, None, self.cell_timeout, threads=1)
        with contextlib.closing(pool.run(units, payload)) as finished:
            for task, results in finished:
                for pc, result in zip(task.cells, results, strict=True):
                    record(pc, result)
        store.consolidate()
        return {key: str(row["status"]) for key, row in record.rows.items()}


def _unpickled(path: Path, digest: str) -> Dataset:
    """The dataset its launcher pickled, once its bytes prove it: the folder may be shared,
    and a pickle put there by anyone else would run code."""
    data = path.read_bytes()
    if hashlib.sha256(data).hexdigest() != digest:
        raise DataError(
            f"{path}: not the dataset its launcher wrote (its SHA-256 differs); not unpickled"
        )
    return pickle.loads(data)


class _Hashing:
    """A binary file that hashes what is written through it."""

    def __init__(self, file: Any) -> None:
        self.file, self.sha = file, hashlib.sha256()

    def write(self, data: bytes) -> int:
        self.sha.update(data)
        return self.file.write(data)


def run_array_task(plugin_files: dict[str, str], task: bytes) -> dict[str, str]:
    """What submitit runs in an array task: the plugin files the launcher loaded, imported
    under the same names, then the :class:`ArrayTask` (unpickled after them, as its
    detectors' classes may live there)."""
    from slipbench.engine.registry import import_plugin_file

    for path in plugin_files.values():
        import_plugin_file(path)
    work: ArrayTask = pickle.loads(task)
    return work()


def _remote(dataset: Dataset, stamp: Stamp, store: ResultsStore, refit: set[str], options):
    """The SLURM executor's side of this run: what each array task runs, and how its rows
    are read back."""
    from slipbench.atomic import atomic_file, make_folder
    from slipbench.engine.registry import PLUGIN_FILES
    from slipbench.engine.slurm import Remote, Resources

    res = options.get("slurm") or Resources()
    folder = make_folder(Path(res.folder) if res.folder else store.folder / "slurm")
    digest = ""
    if dataset.path is not None and stored_fingerprint(dataset.path) == dataset.fingerprint:
        source = str(Path(dataset.path).resolve())
    else:  # built or changed in memory (combined, a subset): the array tasks read this one
        source = str(folder / f"dataset-{dataset.fingerprint}.pkl")
        # written by every launch (a file found there is nobody's word), with its digest
        with atomic_file(source) as file:
            hashing = _Hashing(file)
            pickle.dump(dataset, hashing, pickle.HIGHEST_PROTOCOL)
        digest = hashing.sha.hexdigest()
    plugins = dict(PLUGIN_FILES)

    def work(tasks: list[Task | Batch]) -> tuple[Callable, tuple]:
        runs: dict[int, tuple[Run, list[Cell]]] = {}
        units = []
        for task in tasks:
            members = task.tasks if isinstance(task, Batch) else [task]
            units.append([t.model_key for t in members])
            for pc in task.cells:
                runs.setdefault(id(pc.run), (pc.run, []))[1].append(pc.cell)
        array_task = ArrayTask(
            source,
            replace(stamp, env={}),
            list(runs.values()),
            units,
            str(store.folder.resolve()),
            refit,
            res.cpus_per_task,
            options.get("cell_timeout"),
            digest,
        )
        return run_array_task, (plugins, pickle.dumps(array_task, pickle.HIGHEST_PROTOCOL))

    return Remote(work, store.cell, stamp.run_id, folder)


def _warn_reads(detector: str, fields: dict, warned: set[tuple[str, str]]) -> None:
    """Say once per detector and file that a fit read a file no cache key holds."""
    for path in json.loads(fields.get("unkeyed_reads") or "{}"):
        if (detector, path) not in warned:
            warned.add((detector, path))
            warnings.warn(
                f"detector {detector!r} read {path} while fitting; it is not part of its code "
                "identity (declare it in data_files): cached cells are reused only while its "
                "content is unchanged",
                stacklevel=2,
            )


def _work(
    plan: Plan, task: Task | Batch, store: ResultsStore, refit: set[str], scheduler: str | None
) -> Job | Lockstep:
    """A task's work: its Job, or a batch's Lockstep of its tasks' Jobs. Models of ``refit``
    are fitted again, not loaded."""
    if isinstance(task, Batch):
        return Lockstep(
            [_payload(plan, t, store, t.model_key in refit, scheduler) for t in task.tasks]
        )
    return _payload(plan, task, store, task.model_key in refit, scheduler)


def _payload(
    plan: Plan, task: Task, store: ResultsStore, force: bool, scheduler: str | None
) -> Job:
    """A task's :class:`~slipbench.engine.fitting.Job`: samples are cut here, one task at a time.
    Channels are standardized by the training windows' statistics, the test side's too."""
    first = task.first
    data, kind = plan.data_of(first), first.run.input
    train = data.values(first.windows("train"), first.cell, kind)
    x = train.x
    assert x is not None  # values() cuts the samples
    scales = None
    if kind == "channels":
        scales = channel_scales(x)
        x = standardized(x, scales)
    trials = data.signals.recordings["trial"].to_numpy()  # the bootstrap resamples whole trials
    tests = [
        _stream_test(plan.data_of(pc).signals, pc, scales)
        if pc.streams is not None
        else _window_test(
            plan.data_of(pc).values(pc.windows("test"), pc.cell, kind), trials, scales
        )
        for pc in task.cells
    ]
    model_path = None
    if not scheduler:  # dask workers may not see this disk
        model_path = store.model_path(task.model_key)
        if force:
            Path(f"{model_path}.json").unlink(missing_ok=True)
    return Job(
        first.run.detector,
        first.run.seed,
        first.sampling_rate,
        x,
        train.y,
        tests,
        None if model_path is None else str(model_path),
        first.run.detector_name,
        trials[train.recording],
        first.run.retrain,
    )


def _scales(plan: Plan, pc: PlannedCell) -> dict[str, float]:
    """With a normalization, the median scale the cell's training and test recordings were
    divided by (one value per unit with ``unit``), so a row shows the scales it bridged."""
    if pc.train is None or pc.run.normalize == "none":
        return {}
    data = plan.data_of(pc)
    if data.scales is None:
        return {}
    if pc.streams is not None:
        tested = pc.streams["test"]
    elif pc.test is not None:
        tested = pc.test.recording
    else:  # skipped before its test windows were known
        return {}
    return {
        f"normalize_scale_{side}": float(np.median(data.scales[np.unique(rows), 1]))
        for side, rows in (("train", pc.train.recording), ("test", tested))
        if len(rows)
    }


def _window_test(windows, trials: np.ndarray, scales: np.ndarray | None) -> TestSet:
    x = windows.x if scales is None else standardized(windows.x, scales)
    return TestSet(x, windows.y, trials[windows.recording], windows.strata())


def _stream_test(signals: Signals, pc: PlannedCell, scales: np.ndarray | None = None) -> StreamTest:
    """A streaming cell's recordings, whole, as plain data: the univariate signal, or with
    ``scales`` (the training windows' :func:`channel_scales`) the standardized channels."""
    rec, o, labels = signals.recordings, signals.offsets, signals.sample_labels()
    rates = rec["sampling_rate_hz"].to_numpy(dtype=float)
    streams, stream = pc.streams, pc.cell.stream
    assert streams is not None and stream is not None  # planned as a streaming cell

    def signal(r: int) -> np.ndarray:
        if scales is None:
            return signals.buffer[o[r] : o[r + 1]]
        assert signals.channels is not None  # Signals.from_dataset keeps them
        return standardized(signals.channels[r][1:], scales)

    def recordings(rows: np.ndarray) -> Recordings:
        return Recordings(
            [signal(r) for r in rows],
            [labels[o[r] : o[r + 1]] for r in rows],
            [str(t) for t in rec["trial"].to_numpy()[rows]],
            [str(s) for s in rec["scenario"].to_numpy()[rows]],
            [str(i) for i in rec["recording_id"].to_numpy()[rows]],
            [float(rates[r]) for r in rows],
        )

    return StreamTest(
        recordings(streams["test"]),
        recordings(streams["train"]),
        stream["hop"],
        stream["max_delay_ms"],
    )


def prepare_ahead(runs: list[Run], say_it: bool) -> None:
    """Each run's detector class begins its once-per-machine work beside this process
    (:meth:`BaseDetector.prepare_ahead`, e.g. the LSTM's kernels compiled in a child), to
    overlap reading or simulating the dataset; :func:`evaluate` waits for it before any worker
    starts."""
    for cls in dict.fromkeys(type(run.detector) for run in runs):
        cls.prepare_ahead(_say(say_it))


def _prepare(tasks: list[Task | Batch], say_it: bool) -> None:
    """Each detector class with models to train does its once-per-machine work
    (:meth:`BaseDetector.prepare`, e.g. the LSTM compiling its kernels) before any worker starts,
    so that the workers load what it made instead of each making it at once."""
    classes = dict.fromkeys(type(task.cells[0].run.detector) for task in tasks if task.cells)
    for cls in classes:
        cls.prepare(_say(say_it))


def _say(say_it: bool) -> Callable[[str], None]:
    return (lambda line: print(line, file=sys.stderr, flush=True)) if say_it else (lambda _: None)


def _describe(runs: list[Run]) -> str:
    detector_names = dict.fromkeys(r.detector_name for r in runs)
    protocol_names = dict.fromkeys(r.protocol_name for r in runs)
    return " x ".join(
        next(iter(names)) if len(names) == 1 else f"{len(names)} {kind}"
        for names, kind in ((detector_names, "detectors"), (protocol_names, "protocols"))
    )


def _progress(total: int, done: int, enabled: bool, desc: str):
    """A progress bar: cells done (cached and skipped ones count at once) and the time left."""
    from tqdm import tqdm

    bar = tqdm(
        total=total, initial=done, desc=desc, unit="cell", file=sys.stderr, disable=not enabled
    )
    bar.set_postfix_str(f"{done} cached or skipped", refresh=False)
    return bar


def _shown(bar, cached: int) -> Callable[[dict], None]:
    """Show a model's latest progress report beside the bar (from any thread: tqdm locks)."""
    before = f"{cached} cached or skipped; " if cached else ""

    def show(report: dict) -> None:
        bar.set_postfix_str(before + progress_line(report))

    return show


def progress_line(report: dict) -> str:
    """``lstm: epoch 12/30, loss 0.41`` from a report of ``BaseDetector.report_progress``."""
    step, total = report["step"], report["total"]
    figures = {k: v for k, v in report.items() if k not in ("detector", "step", "total", "unit")}
    return ", ".join(
        [f"{report['detector']}: {report['unit']} {step}" + (f"/{total}" if total else "")]
        + [f"{name} {value:.3g}" for name, value in figures.items()]
    )
