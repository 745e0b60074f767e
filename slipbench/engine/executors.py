"""Where models are fitted: in local worker processes, on a dask cluster, or (``jobs=0``, for
debugging) in this process.

:class:`Executor` takes tasks and a function that turns a task into its
:class:`~slipbench.engine.fitting.Job` (or a :class:`~slipbench.engine.fitting.Lockstep` of
Jobs trained together), and yields every task with its results as they finish.
A worker that overruns the time limit, or ends (the out-of-memory killer, a crash in native
code, a plugin's ``os._exit``, with any exit code), fails its task's cells with the reason and
the phase (fit or test); the run goes on in a fresh worker. Every executor sets the threads a
model may use (:mod:`slipbench.engine.threads`) and passes on the progress models report. An
interrupted run (Ctrl-C, SIGTERM) stops its workers at once: the cells in flight are cancelled
and run again on resume.
"""

from __future__ import annotations

import ast
import pickle
import sys
import time
import types
import uuid
from collections.abc import Callable, Generator, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, wait
from contextlib import suppress
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, TypeVar

import psutil

from slipbench.base import listening
from slipbench.engine import threads, workers
from slipbench.engine.fitting import Job, Lockstep, Result, perform
from slipbench.engine.limits import SCHEDULERS, jobs_problem, scheduler_problem
from slipbench.errors import EnvironmentFault, UsageError

T = TypeVar("T")
Payload = Callable[[T], Job | Lockstep]
Report = Callable[[dict], None]  # what shows a model's progress report
Finished = Generator[tuple[T, list[Result]], None, None]

TICK = 0.1  # seconds between looks at the workers (and the progress they report)
# pebble fails a task itself when its worker ends with any code but 0, within its 0.1 s poll;
# a task still open this long after its worker vanished lost a worker that exited with 0
GRACE = 1.0
STOP = 1.0  # seconds an interrupted worker has to end on SIGTERM before it is killed


def serial(tasks: list[T], payload: Payload, on_report: Report | None) -> Finished:
    sink = workers.throttled(on_report) if on_report else None
    with threads.limited(threads.share(1)):  # restored for the caller when the run ends
        for task in tasks:
            job = payload(task)
            with listening(sink):
                results = perform(job)
            yield task, results


def _failed(n: int, status: str, reason: str) -> list[Result]:
    return [Result({"status": status, "reason": reason})] * n


def _exited(code: int, phase: str) -> str:
    if code < 0:
        return (
            f"the worker process was killed by signal {-code} (exit code {code}; e.g. the "
            f"out-of-memory killer) in {phase}"
        )
    return f"the worker process exited with code {code} in {phase}"


@dataclass
class _Flight(Generic[T]):
    """A task sent to the pool: the worker running it, since when and in which phase, as the
    worker said."""

    task: T
    future: Future
    worker: psutil.Process | None = None
    started: float = 0.0
    phase: str = "fit"
    gone_at: float | None = None  # when its worker was first seen gone

    def outcome(self, now: float, timeout: float | None) -> list[Result] | None:
        """Its results where it is over: done, its worker gone (pebble says why where the
        exit code is not 0, within its 0.1 s poll; past GRACE it exited with 0), or past the
        time limit (its worker is stopped); None while it runs."""
        n = len(self.task.cells)  # type: ignore[attr-defined]
        if self.future.done():
            return self._results(n)
        if self.gone_at is None:
            if self.worker is None:  # queued, or not yet said it started
                return None
            if not _running(self.worker):
                self.gone_at = now
        if self.gone_at is not None:
            return (
                _failed(n, "failed", _exited(0, self.phase)) if now > self.gone_at + GRACE else None
            )
        models = getattr(self.task, "models", 1)
        if timeout and self.worker and now > self.started + timeout * models:
            _stop([self.worker])  # pebble starts another worker
            what = "the model" if models == 1 else f"the {models} models trained together"
            return _failed(
                n, "timeout", f"{what} did not fit and test within {timeout * models:g} s"
            )
        return None

    def _results(self, n: int) -> list[Result]:
        from pebble import ProcessExpired

        try:
            return self.future.result()
        except EnvironmentFault:
            raise  # the machine's fault: the run stops, exit 5
        except ProcessExpired as exc:
            return _failed(n, "failed", _exited(exc.exitcode, self.phase))
        # what the worker sent back instead of results (a KeyboardInterrupt or SystemExit of
        # plugin code too: the user's Ctrl-C reaches this process, not the worker)
        except BaseException as exc:  # noqa: BLE001
            return _failed(n, "failed", f"the worker could not run this model: {exc!r}")


def _process(pid: int) -> psutil.Process | None:
    """The process, known by its start time too: a pid another process takes later is not it."""
    with suppress(psutil.Error):
        return psutil.Process(pid)
    return None


def _running(proc: psutil.Process) -> bool:
    # a zombie has ended: its parent (the fork server, or init where that is gone too) has
    # only not reaped it yet, and in a container init may never do
    with suppress(psutil.Error):
        return proc.is_running() and proc.status() != psutil.STATUS_ZOMBIE
    return False


def _descendants(workers: list[psutil.Process]) -> list[psutil.Process]:
    """The running workers and every process they started."""
    procs = []
    for worker in filter(_running, workers):
        with suppress(psutil.Error):
            procs += [worker, *worker.children(recursive=True)]
    return procs


def _stop(workers: list[psutil.Process]) -> None:
    """End the workers and every process they started: SIGTERM, then SIGKILL after STOP s
    (a worker deep in native code does not see SIGTERM until it returns)."""
    _end(_descendants(workers))


def _end(procs: list[psutil.Process]) -> None:
    """End ``procs`` (psutil knows each by its start time too: a reused pid is left alone)."""
    for method in ("terminate", "kill"):
        for proc in procs:
            with suppress(psutil.Error):
                getattr(proc, method)()
        deadline = time.monotonic() + STOP
        while (procs := [p for p in procs if _running(p)]) and time.monotonic() < deadline:
            time.sleep(0.02)


class _Pool(Generic[T]):
    """pebble's ProcessPool, watched: which worker runs which task (told over a pipe), and
    every worker that vanishes. pebble kills a worker past its time limit and replaces one
    that died, but waits forever on a task whose worker exited with code 0, and on Ctrl-C
    waits for the tasks in flight."""

    def __init__(
        self,
        processes: int,
        timeout: float | None,
        on_report: Report | None,
        per_model: int,
    ) -> None:
        import multiprocessing

        from pebble import ProcessPool

        from slipbench.engine.registry import PLUGIN_FILES

        # a fresh server process, not a fork of this one: a process that already ran OpenMP
        # threads (numba's parallel kernels) cannot fork safely
        context = multiprocessing.get_context("forkserver")
        self.reader, writer = context.Pipe(duplex=False)
        self.pool = ProcessPool(
            max_workers=max(1, processes),  # pebble starts them all: never more than tasks
            initializer=workers.start,
            initargs=(per_model, dict(PLUGIN_FILES), writer, on_report is not None),
            context=context,
        )
        self.writer, self.timeout, self.on_report = writer, timeout, on_report
        self.flights: dict[int, _Flight] = {}
        self.workers: list[psutil.Process] = []  # every worker that said it started

    def send(self, number: int, task: T, job: Job | Lockstep) -> None:
        # pickled here, so that no plugin code runs in pebble's own reading of the task
        blob = pickle.dumps(job, protocol=pickle.HIGHEST_PROTOCOL)
        # the time limit is kept here, from the worker's word that it started: pebble's would
        # race with a worker that exited with 0 (see _Flight.outcome)
        future = self.pool.schedule(workers.run, args=(number, blob))
        self.flights[number] = _Flight(task, future)

    def finished(self) -> Iterator[tuple[T, list[Result]]]:
        """Tasks over since the last call (waits up to TICK for one)."""
        wait([f.future for f in self.flights.values()], TICK, FIRST_COMPLETED)
        self._read()
        now = time.monotonic()
        for number, flight in list(self.flights.items()):
            results = flight.outcome(now, self.timeout)
            if results is not None:
                del self.flights[number]
                yield flight.task, results

    def _read(self) -> None:
        report = None
        for message in workers.received(self.reader):
            kind, *rest = message
            if kind == "hello" and (worker := _process(rest[0])):
                self.workers.append(worker)
            elif kind == "start" and rest[0] in self.flights:
                flight = self.flights[rest[0]]
                flight.worker, flight.started = _process(rest[1]), time.monotonic()
                if flight.worker is None:  # ended before this look
                    flight.gone_at = flight.started
            elif kind == "phase" and rest[0] in self.flights:
                self.flights[rest[0]].phase = rest[1]
            elif kind == "report":
                report = rest[0]
        if report is not None and self.on_report is not None:
            self.on_report(report)  # the latest only: a few redraws a second

    def close(self, interrupted: bool) -> None:
        """Stop the pool; ``interrupted``: its workers first, without waiting for their tasks.
        Every process a plugin started in a worker ends with it, even one in a session of its
        own (which no signal to the worker's process group reaches): found before the workers
        end, while they are still its parents."""
        self._read()  # workers that started meanwhile
        started = _descendants(self.workers)
        self.pool.stop()
        if interrupted:
            _stop(self.workers)
        self.pool.join()
        _end(started)
        self.reader.close()
        self.writer.close()


def process_pool(
    tasks: list[T], payload: Payload, executor: Executor, on_report: Report | None
) -> Finished:
    """``executor.jobs`` local worker processes (never more than tasks); at most two tasks per
    worker in flight, so their windows are not all in memory at once. Nothing to run starts no
    worker."""
    if not tasks:
        return
    jobs = executor.jobs
    pool: _Pool[T] = _Pool(
        min(jobs, len(tasks)), executor.timeout, on_report, executor.threads or threads.share(jobs)
    )
    queue = iter(enumerate(tasks))
    interrupted = True
    try:
        while True:
            for number, task in queue:
                pool.send(number, task, payload(task))
                if len(pool.flights) >= 2 * jobs:
                    break
            if not pool.flights:
                interrupted = False
                return
            yield from pool.finished()
    finally:
        pool.close(interrupted)


def dask_client(address: str):
    try:
        from distributed import Client
    except ImportError:
        raise UsageError(
            "--scheduler needs dask.distributed: pip install 'slipbench[dask]'"
        ) from None
    try:
        if Path(address).is_file():  # a scheduler file, as `dask scheduler` writes it
            return Client(scheduler_file=address, timeout="3s")
        return Client(address, timeout="3s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise UsageError(f"cannot reach the dask scheduler at {address}: {exc}") from None


def dask(tasks: list[T], payload: Payload, address: str, on_report: Report | None) -> Finished:
    """A dask.distributed cluster; results arrive as they complete. Progress comes as worker
    events on a topic of this run (a message through the scheduler, a few a second per task)."""
    from distributed import as_completed

    client = dask_client(address)
    topic = f"slipbench-progress-{uuid.uuid4().hex}" if on_report else ""
    if on_report:  # called in the client's event loop: throttled once more for all tasks
        show = workers.throttled(on_report)
        # an event is (time, message); the scheduler adds the worker's address to a message
        client.subscribe_topic(
            topic, lambda event: show({k: v for k, v in event[1].items() if k != "worker"})
        )
    futures: dict[Any, T] = {}
    try:
        per_host = _threads_per_host(client)
        for t in tasks:
            futures[client.submit(_on_dask, payload(t), per_host, topic, pure=False)] = t
        for future in as_completed(futures):
            task = futures.pop(future)
            yield task, _dask_results(future, len(task.cells))  # type: ignore[attr-defined]
    finally:
        # what is still in flight (an interrupted run) is cancelled, not left to the cluster;
        # a task already running ends in its thread, its result dropped
        if futures:
            client.cancel(list(futures), force=True)
        client.close()


def _threads_per_host(client) -> dict[str, int]:
    """The threads of the cluster's workers on each machine, which share its cores."""
    per_host: dict[str, int] = {}
    for worker in client.scheduler_info(n_workers=-1)["workers"].values():
        per_host[worker["host"]] = per_host.get(worker["host"], 0) + worker["nthreads"]
    return per_host


def _on_dask(job: Job | Lockstep, per_host: dict[str, int], topic: str) -> list[Result]:
    """A task on a dask worker: its model gets the share of the machine's cores that the run's
    worker threads on it leave, set and not restored (every task of the run on this worker sets
    the same, and restoring would race between the worker's threads)."""
    from distributed import get_worker
    from distributed.comm import get_address_host

    worker = get_worker()
    at_once = per_host.get(get_address_host(worker.address), worker.state.nthreads)
    n = threads.share(at_once)
    threads.set_environment(n, numba=False)
    threads.set_threads(n)
    sink = workers.throttled(lambda r: worker.log_event(topic, r)) if topic else None
    with listening(sink):
        return perform(job)


def _dask_results(future, n: int) -> list[Result]:
    try:
        return future.result()
    except EnvironmentFault:
        raise
    # a worker lost three times (KilledWorker), or what a task raised outside the plugin's
    # code: its cells fail, the run goes on
    except (Exception, SystemExit) as exc:  # noqa: BLE001
        return _failed(n, "failed", f"the dask task failed: {exc!r}")


def unguarded_script() -> str:
    """``file:line`` of the statement of the running script (``__main__``, run from a file) that
    is calling slipbench outside an ``if __name__ == "__main__":`` block, or "" (no such script:
    the command line, a REPL, ``python -c``, a notebook, a guarded call).

    Worker processes import the script again before they take work (multiprocessing's spawn
    and forkserver methods, the default on macOS and Windows and here): without the guard each
    would run the script's calls anew and die, and the run would end in "All workers expired"."""
    main = sys.modules.get("__main__")
    if main is None or not getattr(main, "__file__", None):
        return ""
    frame: types.FrameType | None = sys._getframe(1)
    outer = None
    while frame is not None:
        if frame.f_globals is vars(main) and frame.f_code.co_name == "<module>":
            outer = frame
        frame = frame.f_back
    if outer is None:  # called from a thread, or from code the script does not run at import
        return ""
    file, line = outer.f_code.co_filename, outer.f_lineno
    try:
        tree = ast.parse(Path(file).read_bytes())
    except (OSError, SyntaxError, ValueError):
        return ""
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.If)
            and "__name__" in {n.id for n in ast.walk(node.test) if isinstance(n, ast.Name)}
            and node.lineno <= line <= (node.end_lineno or node.lineno)
        ):
            return ""
    return f"{file}:{line}"


def workers_for(jobs: int, scheduler: str | None, timeout: float | None) -> int:
    """The local worker processes to start for ``jobs``: ``jobs`` itself, or 0 (run in this
    process) where a script without an ``if __name__ == "__main__":`` guard asked for one (the
    default), since its workers would run the script again. Such a script asking for more, or
    for a time limit (which needs a worker to kill), is refused with one line saying what to add,
    as are more jobs than the machine can run (:func:`jobs_problem`) and a ``scheduler`` that
    names no executor (:func:`scheduler_problem`)."""
    if scheduler and (problem := scheduler_problem(scheduler)):
        raise UsageError(f"scheduler {scheduler!r}: {problem}")
    if not scheduler and (problem := jobs_problem(jobs)):
        raise UsageError(f"jobs={jobs}: {problem}")
    if scheduler or jobs == 0:
        return jobs
    where = unguarded_script()
    if not where:
        return jobs
    if jobs == 1 and not timeout:
        return 0
    asked = f"jobs={jobs}" + (f" with cell_timeout={timeout:g}" if timeout else "")
    raise UsageError(
        f"{where}: {asked} starts worker processes, which import this script again: put its "
        'calls under `if __name__ == "__main__":` (or use jobs=1 without a time limit, which '
        "runs in this process)"
    )


@dataclass(frozen=True)
class Executor:
    """Where tasks run: ``jobs`` local worker processes (0: in this process, with no
    protection against a crash and no time limit), a SLURM job array (``scheduler`` one of
    :data:`SCHEDULERS`, with ``resources``), or the dask scheduler at ``scheduler``;
    ``timeout``: seconds one model may take. ``threads``: a model's threads in a local worker
    (None: this machine's share; an array task gives its own)."""

    jobs: int = 1
    scheduler: str | None = None
    timeout: float | None = None
    resources: Any = None  # slipbench.engine.slurm.Resources
    threads: int | None = None

    def run(
        self, tasks: list[T], payload: Payload, on_report: Report | None = None, remote: Any = None
    ) -> Finished:
        """Every task with its results, as they finish; ``on_report`` shows the progress a model
        reports (None: nobody listens, and workers send none). A job array needs ``remote``
        (:class:`slipbench.engine.slurm.Remote`): its tasks cut their own payloads."""
        if self.scheduler in SCHEDULERS:
            from slipbench.engine import slurm

            return slurm.run(tasks, remote, self.scheduler, self.resources, self.timeout)
        if self.scheduler:
            return dask(tasks, payload, self.scheduler, on_report)
        if self.jobs == 0:
            if self.timeout:
                raise UsageError("a time limit needs worker processes: use --jobs 1 or more")
            return serial(tasks, payload, on_report)
        return process_pool(tasks, payload, self, on_report)
