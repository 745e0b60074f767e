"""Where models are fitted: in local worker processes, on a dask cluster, or (``jobs=0``, for
debugging) in this process.

Each executor takes tasks and a function that turns a task into the arguments of
:func:`slipbench.engine.fitting.fit_and_test`, and yields every task with its results as they finish.
A worker that overruns the time limit, or dies (the out-of-memory killer, a crash in native
code), fails its task's cells with the reason; the run goes on in a fresh worker.
"""

from __future__ import annotations

import ast
import os
import sys
import types
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

from slipbench.engine.fitting import Result, fit_and_test
from slipbench.errors import UsageError

T = TypeVar("T")
Payload = Callable[[T], tuple]


def serial(tasks: list[T], payload: Payload) -> Iterator[tuple[T, list[Result]]]:
    for task in tasks:
        yield task, fit_and_test(*payload(task))


def _worker_init(jobs: int, plugin_files: dict[str, str]) -> None:
    # share the machine's cores between the workers instead of oversubscribing them
    threads = max(1, (os.cpu_count() or 1) // jobs)
    os.environ["OMP_NUM_THREADS"] = str(threads)
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(threads)
    from slipbench.engine.registry import import_plugin_file

    for path in plugin_files.values():  # the folder plugins the parent loaded, under the same names
        try:
            import_plugin_file(path)
        except Exception:  # noqa: BLE001 - its cells fail with the error when it is used
            pass


def _failed(n: int, status: str, reason: str) -> list[Result]:
    return [({"status": status, "reason": reason}, None)] * n


def process_pool(
    tasks: list[T], payload: Payload, jobs: int, timeout: float | None
) -> Iterator[tuple[T, list[Result]]]:
    """Local worker processes; at most two tasks per worker in flight, so their windows are not
    all in memory at once. pebble, unlike concurrent.futures, kills a worker past its time limit
    and replaces a worker that died.

    Workers start from a fresh server process ("forkserver"), not a fork of this one: a process
    that already ran OpenMP threads (numba's parallel kernels) cannot fork safely."""
    import multiprocessing
    from concurrent.futures import TimeoutError as FutureTimeout

    from pebble import ProcessExpired, ProcessPool

    from slipbench.engine.registry import PLUGIN_FILES

    context = multiprocessing.get_context("forkserver")
    with ProcessPool(
        max_workers=jobs,
        initializer=_worker_init,
        initargs=(jobs, dict(PLUGIN_FILES)),
        context=context,
    ) as pool:
        pending: list[Any] = []
        queue = iter(tasks)
        while True:
            for task in queue:
                pending.append(
                    (pool.schedule(fit_and_test, args=payload(task), timeout=timeout), task)
                )
                if len(pending) >= 2 * jobs:
                    break
            if not pending:
                return
            future, task = pending.pop(0)
            n = len(task.cells)
            try:
                yield task, future.result()
            except FutureTimeout:
                yield (
                    task,
                    _failed(n, "timeout", f"the model did not fit and test within {timeout:g} s"),
                )
            except ProcessExpired as exc:
                killed = exc.exitcode is not None and exc.exitcode < 0
                yield (
                    task,
                    _failed(
                        n,
                        "failed",
                        f"the worker process died (exit code {exc.exitcode}"
                        + (": killed by a signal, e.g. the out-of-memory killer" if killed else "")
                        + ") while fitting or testing this model",
                    ),
                )


def dask_client(address: str):
    try:
        from distributed import Client
    except ImportError:
        raise UsageError(
            "--scheduler needs dask.distributed: pip install 'slipbench[dask]'"
        ) from None
    try:
        return Client(address, timeout="3s")
    except (OSError, TimeoutError) as exc:
        raise UsageError(f"cannot reach the dask scheduler at {address}: {exc}") from None


def dask(tasks: list[T], payload: Payload, address: str) -> Iterator[tuple[T, list[Result]]]:
    """A dask.distributed cluster; results arrive as they complete."""
    from distributed import as_completed

    client = dask_client(address)
    try:
        futures = {client.submit(fit_and_test, *payload(t), pure=False): t for t in tasks}
        for future in as_completed(futures):
            yield futures[future], future.result()
    finally:
        client.close()


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
    for a time limit (which needs a worker to kill), is refused with one line saying what to add."""
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


def execute(
    tasks: list[T],
    payload: Payload,
    jobs: int = 1,
    scheduler: str | None = None,
    timeout: float | None = None,
) -> Iterator[tuple[T, list[Result]]]:
    """Run tasks on the executor the options ask for: ``jobs`` worker processes, or in this
    process for ``jobs=0`` (no protection against a crash, no time limit)."""
    if scheduler:
        return dask(tasks, payload, scheduler)
    if jobs == 0:
        if timeout:
            raise UsageError("a time limit needs worker processes: use --jobs 1 or more")
        return serial(tasks, payload)
    return process_pool(tasks, payload, jobs, timeout)
