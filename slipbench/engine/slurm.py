"""Where models are fitted on a SLURM cluster: job arrays through submitit.

The run's tasks (a model, or a lockstep batch of models kept together) are dealt into shards,
one array task each; an array task re-plans its own cells from the dataset on the shared file
system, fits them in a local process pool of ``cpus_per_task`` workers (with the run's cell
time limit) and writes each verified cell into the shared results folder as it finishes. The
launching process only submits and gathers: it reads back the cells each array task wrote
(those of this run) and fails with the reason the cells it did not write (a task past its time
limit, a lost node, a crash). Nothing depends on the launcher surviving: a new launch of the
same command skips the cells on disk and adopts the array tasks of an earlier launch that are
still queued or running, rather than submitting their cells twice.

The launcher never unpickles what an array task left (submitit's ``*_result.pkl``): the results
folder may be shared, and a pickle planted there would run code. What an array task did is read
from the cells it wrote, each proved by its digests, from its state (sacct, or the local
process) and from the last line of its error log, read as text.

``submitit-local`` runs the same path through submitit's local executor (the tests' and a
reviewer's check), each array task a local process.

Resources come from a run file's ``[slurm]`` table or ``--slurm KEY=VALUE``; a sub-table named
after a detector (``[slurm.lstm]``, ``--slurm lstm.gpus_per_node=1``) gives that detector's
tasks their own, in an array of their own.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Generator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from slipbench.engine.fitting import Result, Stored
from slipbench.errors import EnvironmentFault, UsageError

LOCAL = "submitit-local"
#: what each key of a [slurm] table takes: (types, meaning); the per-detector sub-tables take
#: those of PER_DETECTOR
KEYS: dict[str, tuple[type | tuple[type, ...], str]] = {
    "partition": (str, "a partition name"),
    "account": (str, "an account name"),
    "qos": (str, "a quality of service name"),
    "constraint": (str, "a node feature constraint"),
    "time": (int, "minutes an array task may run, an int > 0"),
    "cpus_per_task": (int, "cores per array task, an int >= 1"),
    "mem_gb": ((int, float), "memory per array task in GB, > 0"),
    "gpus_per_node": (int, "GPUs per array task, an int >= 0"),
    "array_parallelism": (int, "array tasks running at once, an int >= 1"),
    "tasks": (int, "array tasks at most per detector's resources, an int >= 1"),
    "setup": (list, "a list of shell lines run before each array task"),
    "folder": (str, "a folder for submitit's scripts and logs"),
}
PER_DETECTOR = (
    *("partition", "account", "qos", "constraint"),
    *("time", "cpus_per_task", "mem_gb", "gpus_per_node"),
)
MARGIN = 1.25  # a task's time limit: its models' cell time limits, plus a quarter
STARTUP_S = 600.0  # and ten minutes to start, read the dataset and plan its cells
POLL_S = {LOCAL: 0.5, "slurm": 15.0}  # seconds between looks at the array tasks
ACTIVE = {"PENDING", "RUNNING", "REQUEUED", "CONFIGURING", "COMPLETING", "RESIZING", "SUSPENDED"}
#: states of a task SLURM ended before it could write a result
KILLED = {"TIMEOUT", "CANCELLED", "NODE_FAIL", "OUT_OF_MEMORY", "PREEMPTED", "BOOT_FAIL"}
#: states of a task that ended by returning (SLURM's, submitit's local executor's)
RETURNED = {"COMPLETED", "FINISHED"}
SHARED_FS_S = 30.0  # how long cells of a finished task may take to show on a shared file system
LOG_TAIL = 64 * 1024  # bytes of a task's error log read for the line that says why it failed
SUBMITTED = "submitted.json"  # array tasks of every launch, and the cells each holds


class SlurmKeyError(UsageError):
    """A [slurm] key or value a cluster cannot take: ``key`` names it (``lstm.time`` for a
    detector's), so a run file's message can give its line."""

    def __init__(self, key: str, what: str) -> None:
        super().__init__(f"[slurm] {key}: {what}")
        self.key, self.what = key, what


@dataclass(frozen=True)
class Resources:
    """What one array task asks the cluster for, and how the run is cut into array tasks.

    ``time`` None: derived from the run's cell time limit (see :func:`time_limit`).
    ``detectors``: per detector id, the keys of :data:`PER_DETECTOR` that differ for its tasks.
    """

    partition: str | None = None
    account: str | None = None
    qos: str | None = None
    constraint: str | None = None
    time: int | None = None
    cpus_per_task: int = 1
    mem_gb: float = 4.0
    gpus_per_node: int = 0
    array_parallelism: int = 64
    tasks: int | None = None  # default: 4 x array_parallelism (four waves balance the load)
    setup: tuple[str, ...] = ()
    folder: str | None = None
    detectors: dict[str, dict[str, Any]] = field(default_factory=dict)

    def of(self, detector: str) -> Resources:
        """The resources of ``detector``'s array tasks."""
        return replace(self, detectors={}, **self.detectors.get(detector, {}))

    @property
    def max_tasks(self) -> int:
        return self.tasks or 4 * self.array_parallelism

    def described(self) -> str:
        """``partition gpu, 8 cores, 16 GB, 1 GPU, 120 min``: a line of the plan."""
        parts = [f"partition {self.partition}"] if self.partition else []
        parts += [f"{self.cpus_per_task} core{'s' * (self.cpus_per_task > 1)}"]
        parts += [f"{self.mem_gb:g} GB"]
        parts += [f"{self.gpus_per_node} GPU{'s' * (self.gpus_per_node > 1)}"] * bool(
            self.gpus_per_node
        )
        return ", ".join(parts)


def _of_type(value: object, types: type | tuple[type, ...]) -> bool:
    return isinstance(value, types)  # kept apart: mypy would narrow ``value`` to object


LOWEST = {"time": 1, "cpus_per_task": 1, "gpus_per_node": 0, "array_parallelism": 1, "tasks": 1}


def _check(key: str, value: Any) -> Any:
    name = key.rsplit(".", 1)[-1]
    types, meaning = KEYS[name]
    if isinstance(value, bool) or not _of_type(value, types):
        raise SlurmKeyError(key, f"must be {meaning}, got {value!r}")
    if name in LOWEST and value < LOWEST[name] or name == "mem_gb" and not value > 0:
        raise SlurmKeyError(key, f"must be {meaning}, got {value!r}")
    if name == "setup":
        if not all(isinstance(line, str) for line in value):
            raise SlurmKeyError(key, f"must be {meaning}, got {value!r}")
        return tuple(value)
    return float(value) if name == "mem_gb" else value


def resources(table: dict[str, Any], detectors: tuple[str, ...] = ()) -> Resources:
    """A checked [slurm] table (``detectors``: the ids its sub-tables may name; empty: any)."""
    top: dict[str, Any] = {}
    per: dict[str, dict[str, Any]] = {}
    for key, value in table.items():
        if isinstance(value, dict):
            if detectors and key not in detectors:
                raise SlurmKeyError(
                    key,
                    f"not a detector of this run ({', '.join(detectors)}); a sub-table "
                    "gives one detector's tasks their own resources",
                )
            for sub, v in value.items():
                if sub not in PER_DETECTOR:
                    raise SlurmKeyError(
                        f"{key}.{sub}", f"unknown key; a detector's takes {', '.join(PER_DETECTOR)}"
                    )
                per.setdefault(key, {})[sub] = _check(f"{key}.{sub}", v)
        elif key in KEYS:
            top[key] = _check(key, value)
        else:
            raise SlurmKeyError(key, f"unknown key; [slurm] takes {', '.join(KEYS)}")
    return Resources(**top, detectors=per)


def from_options(items: tuple[str, ...], table: dict[str, Any] | None = None) -> dict[str, Any]:
    """``table`` (a run file's [slurm]) with ``--slurm KEY=VALUE`` items over it; a VALUE is
    JSON where it parses (``time=120``, ``setup=["module load cuda"]``), text otherwise, and
    ``lstm.gpus_per_node=1`` sets one detector's."""
    out: dict[str, Any] = {
        k: dict(v) if isinstance(v, dict) else v for k, v in (table or {}).items()
    }
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key:
            raise UsageError(f"--slurm {item!r}: expected KEY=VALUE, e.g. --slurm partition=cpu")
        try:
            value = json.loads(text)
        except json.JSONDecodeError:
            value = text
        detector, dot, name = key.rpartition(".")
        if dot:
            out.setdefault(detector, {})[name] = value
        else:
            out[key] = value
    return out


def time_limit(res: Resources, limits: list[float], workers: int) -> int:
    """Minutes an array task may run: ``res.time`` where given, else its models' time limits
    (``limits``, seconds each: the cell time limit x the models a task trains) as ``workers``
    run them, longest first (at most their sum over the workers plus the longest), with
    :data:`MARGIN` and :data:`STARTUP_S`."""
    if res.time:
        return res.time
    worst = sum(limits) / max(workers, 1) + max(limits, default=0.0)
    return math.ceil((STARTUP_S + MARGIN * worst) / 60)


def array_minutes(res: Resources, shards: list[Shard], timeout: float | None) -> int | None:
    """The time limit of an array of ``shards`` (minutes): ``res.time``, else the longest its
    shards' models' cell time limits give (:func:`time_limit`); None where neither is set."""
    if res.time:
        return res.time
    if not timeout:
        return None
    return max(
        time_limit(res, [timeout * t.models for t in s.tasks], res.cpus_per_task) for s in shards
    )


@dataclass
class Shard:
    """Tasks one array task runs, all of one detector's resources."""

    detector: str
    tasks: list[Any]
    weight: float = 0.0


def dealt(tasks: list[Any], res: Resources, weight: Callable[[Any], float]) -> list[Shard]:
    """The tasks dealt into shards: per detector's resources at most ``max_tasks`` shards,
    each task whole (a lockstep batch stays together), longest first onto the lightest shard
    (``weight``: a task's estimated seconds, or its models)."""
    by_detector: dict[str, list[Any]] = {}
    for task in tasks:
        by_detector.setdefault(_detector(task), []).append(task)
    out: list[Shard] = []
    for detector, mine in by_detector.items():
        shards = [Shard(detector, []) for _ in range(min(len(mine), res.max_tasks))]
        for task in sorted(mine, key=weight, reverse=True):
            lightest = min(shards, key=lambda s: (s.weight, len(s.tasks)))
            lightest.tasks.append(task)
            lightest.weight += weight(task)
        out += shards
    return out


def _detector(task: Any) -> str:
    first = task.tasks[0].first if hasattr(task, "tasks") else task.first
    return first.run.detector_name


@dataclass
class Remote:
    """What the engine gives the SLURM executor: ``work(tasks)``, the function an array task
    runs for ``tasks`` and its arguments (plain data: it is pickled to the shared folder);
    ``stored(key)``, a cell's row as an array task wrote it (None: not written);
    ``run_id``, which rows are this run's; ``folder``, where submitit keeps its files."""

    work: Callable[[list[Any]], tuple[Callable[..., Any], tuple]]
    stored: Callable[[str], dict | None]
    run_id: str
    folder: Path


def _executor(folder: Path, scheduler: str, res: Resources, minutes: int, name: str):
    import submitit

    executor = submitit.AutoExecutor(folder, cluster="local" if scheduler == LOCAL else "slurm")
    params: dict[str, Any] = {
        "name": f"slipbench-{name}",
        "timeout_min": minutes,
        "cpus_per_task": res.cpus_per_task,
        "mem_gb": res.mem_gb,
        "gpus_per_node": res.gpus_per_node,
        "slurm_array_parallelism": res.array_parallelism,
    }
    if res.setup:
        params["slurm_setup"] = list(res.setup)
    for key in ("partition", "account", "qos", "constraint"):
        if getattr(res, key):
            params[f"slurm_{key}"] = getattr(res, key)
    executor.update_parameters(**params)
    return executor


def needs_submitit() -> None:
    try:
        import submitit  # noqa: F401
    except ImportError:
        raise UsageError(
            "--scheduler slurm and submitit-local need submitit: pip install 'slipbench[slurm]'"
        ) from None


@dataclass
class _Array:
    """The array tasks in flight: each job with the tasks it holds, and its time limit."""

    jobs: dict[Any, list[Any]] = field(default_factory=dict)
    minutes: dict[str, int] = field(default_factory=dict)  # job id -> its time limit


def run(
    tasks: list[Any],
    remote: Remote,
    scheduler: str,
    res: Resources,
    timeout: float | None,
) -> Generator[tuple[Any, list[Result]], None, None]:
    """Every task with its results as its array task ends: rows the array task stored (this
    run's, read back) or, for cells it did not store, a failed or timeout result saying why.
    An interrupted launcher (Ctrl-C, SIGTERM) cancels its array tasks; one that is killed
    leaves them running, and the next launch adopts them."""
    needs_submitit()
    from submitit.core.utils import UncompletedJobError

    flight = _adopted(tasks, remote.folder, scheduler)
    adopted = {id(t) for ts in flight.jobs.values() for t in ts}
    arrays: dict[str, list[Shard]] = {}  # one job array per detector's resources
    for shard in dealt([t for t in tasks if id(t) not in adopted], res, lambda t: t.models):
        arrays.setdefault(shard.detector, []).append(shard)
    # every array's time limit before the first is submitted: a refusal leaves nothing queued
    minutes = {d: _minutes(scheduler, res.of(d), shards, timeout) for d, shards in arrays.items()}
    interrupted = True
    try:
        for detector, shards in arrays.items():
            _submit_into(flight, shards, remote, (scheduler, res.of(detector), minutes[detector]))
        while flight.jobs:
            done = [job for job in flight.jobs if _done(job)]
            for job in done:
                for task in flight.jobs.pop(job):
                    yield task, _results(task, job, remote, flight.minutes.get(job.job_id))
            if not done:
                _pause(POLL_S[scheduler])
        interrupted = False
    finally:
        if interrupted:
            for job in flight.jobs:
                try:
                    job.cancel(check=False)
                except (OSError, UncompletedJobError):
                    pass


def _minutes(scheduler: str, res: Resources, shards: list[Shard], timeout: float | None) -> int:
    minutes = array_minutes(res, shards, timeout)
    if minutes is None:
        raise UsageError(
            f"--scheduler {scheduler}: the array tasks of {shards[0].detector} need a time "
            "limit: give [slurm] time (minutes; --slurm time=MINUTES) or a cell time limit "
            "(--cell-timeout, [run] cell_timeout), from which each task's is derived"
        )
    return minutes


def _pause(seconds: float) -> None:
    time.sleep(seconds)  # a look at the array tasks every so often (the tests look at once)


def _submit_into(
    flight: _Array, shards: list[Shard], remote: Remote, how: tuple[str, Resources, int]
) -> None:
    """Submit ``shards`` (one detector's) as one job array, as ``how`` says (scheduler, the
    detector's resources, the time limit in minutes), and note its tasks in ``SUBMITTED`` so
    that a later launch finds them."""
    from submitit.core.utils import FailedSubmissionError

    scheduler, res, minutes = how
    executor = _executor(remote.folder, scheduler, res, minutes, shards[0].detector)
    work = [remote.work(s.tasks) for s in shards]
    try:
        with executor.batch():
            jobs = [executor.submit(fn, *args) for fn, args in work]
    except (FailedSubmissionError, OSError) as exc:
        raise EnvironmentFault(
            remote.folder,
            f"sbatch refused {len(shards)} array tasks of {shards[0].detector}: {exc}",
            "submit job arrays from",
        ) from None
    for job, shard in zip(jobs, shards, strict=True):
        flight.jobs[job] = shard.tasks
        flight.minutes[job.job_id] = minutes
    _note(remote.folder, scheduler, {j.job_id: _keys(s.tasks) for j, s in zip(jobs, shards)})


def _keys(tasks: list[Any]) -> list[str]:
    return [pc.key for t in tasks for pc in t.cells]


def _note(folder: Path, scheduler: str, jobs: dict[str, list[str]]) -> None:
    from slipbench.atomic import write_text_atomic

    path = folder / SUBMITTED
    known = _submitted(path)
    known.setdefault(scheduler, {}).update(jobs)
    write_text_atomic(path, json.dumps(known, sort_keys=True))


def _submitted(path: Path) -> dict[str, dict[str, list[str]]]:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _adopted(tasks: list[Any], folder: Path, scheduler: str) -> _Array:
    """Array tasks an earlier launch submitted that SLURM still holds (queued or running):
    the tasks of this run whose cells they hold are gathered from them, not submitted again.
    Local array tasks end with their launcher's session, so only ``slurm`` adopts."""
    flight = _Array()
    earlier = _submitted(folder / SUBMITTED).get(scheduler, {})
    if scheduler != "slurm" or not earlier:
        return flight
    from submitit.slurm.slurm import SlurmJob

    by_key = {pc.key: t for t in tasks for pc in t.cells}
    for job_id, keys in earlier.items():
        held = [by_key[k] for k in keys if k in by_key]
        if not held:
            continue
        job: Any = SlurmJob(folder, job_id)
        if job.state not in ACTIVE:
            continue
        unique, holds = list({id(t): t for t in held}.values()), set(keys)
        # a task is adopted only where this job holds every one of its cells
        whole = [t for t in unique if all(pc.key in holds for pc in t.cells)]
        if whole:
            flight.jobs[job] = whole
            for t in whole:
                for pc in t.cells:
                    del by_key[pc.key]
    return flight


def _done(job: Any) -> bool:
    """Whether an array task ended, by its scheduler's word: submitit's ``done`` would also
    take a result file in the (possibly shared) folder for it."""
    from submitit.slurm.slurm import SlurmJob

    if isinstance(job, SlurmJob):
        return bool(job.watcher.is_done(job.job_id, mode="standard"))
    return bool(job.done())  # a local task: its process has ended


def _stored(task: Any, remote: Remote) -> dict[str, dict]:
    """The rows of ``task``'s cells in the results folder, each proved by its digests: this
    run's, or a finished one an earlier launch's task wrote meanwhile (its key is the content
    address: the same cell)."""
    out = {}
    for pc in task.cells:
        row = remote.stored(pc.key)
        if row is not None and (
            row.get("run_id") == remote.run_id or row.get("status") in ("ok", "skipped")
        ):
            out[pc.key] = row
    return out


def _results(task: Any, job: Any, remote: Remote, minutes: int | None) -> list[Result]:
    """A task's results once its array task ended: its rows as stored there, or why not."""
    why = _ended(job, minutes)
    rows = _stored(task, remote)
    waited = 0.0
    while why is None and len(rows) < len(task.cells) and waited < SHARED_FS_S:
        time.sleep(1.0)  # a task that returned wrote its cells: a shared folder may lag
        waited += 1.0
        rows = _stored(task, remote)
    out: list[Result] = []
    for pc in task.cells:
        if pc.key in rows:
            out.append(Stored(rows[pc.key]))
        elif why is None:
            out.append(
                Result(
                    {
                        "status": "failed",
                        "reason": f"array task {job.job_id} ended without this cell in the "
                        f"results folder: is it on a file system the nodes share?",
                    }
                )
            )
        else:
            out.append(Result(dict(why)))
    return out


def _killed(state: str) -> bool:
    """SLURM ended the task before it could write a result (its time, a node, memory)."""
    return bool(state) and state.split()[0] in KILLED


def _ended(job: Any, minutes: int | None) -> dict[str, str] | None:
    """None where the array task ended well, else the status and reason of the cells it did
    not store: from its state and its error log, never from its result file."""
    state = str(job.state)
    if state.startswith("TIMEOUT"):
        return {
            "status": "timeout",
            "reason": f"array task {job.job_id} reached its time limit ({minutes} min) "
            "before this cell finished",
        }
    word = state.split()[0] if state.split() else ""
    if word == "COMPLETED":  # SLURM's word that the task returned
        return None
    raised = _raised_in_log(Path(job.paths.stderr))
    if raised and not _killed(state):
        return {"status": "failed", "reason": f"array task {job.job_id} failed: {raised}"}
    if word in RETURNED:  # a local task's process ended, and its log shows no exception
        return None
    return {
        "status": "failed",
        "reason": f"array task {job.job_id} ended {state} before this cell finished "
        f"(log: {job.paths.stderr})",
    }


def _raised_in_log(path: Path) -> str:
    """The exception a task's error log ends with (its traceback's last line), or ""."""
    try:
        with path.open("rb") as log:
            log.seek(max(log.seek(0, 2) - LOG_TAIL, 0))
            tail = log.read().decode("utf-8", "replace")
    except OSError:
        return ""
    if "Traceback (most recent call last):" not in tail:
        return ""
    lines = [line for line in tail.splitlines() if line.strip()]
    return lines[-1].strip() if lines else ""
