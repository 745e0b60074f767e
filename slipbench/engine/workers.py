"""The worker side of the local process pool: what sets up a worker process (threads, folder
plugins, the pipe to the parent) and what runs one task in it.

A worker tells the parent what it does over one pipe the parent made before the pool started:
``("hello", pid)`` when it starts, ``("start", task, pid)`` and ``("phase", task, "test")``
as a task goes, and ``("report", {...})``, a model's progress (``BaseDetector.report_progress``),
a few per second at most. The parent learns from them which process runs which task, in which
phase, so that a worker that vanishes (any exit code) fails that task's cells, and which
processes to stop when the run is interrupted. A write never blocks a fit: the pipe is
non-blocking, and a report the parent has no room for, or no longer reads, is dropped.
"""

from __future__ import annotations

import os
import pickle
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any

from slipbench.base import listening
from slipbench.engine import threads
from slipbench.engine.fitting import Result, perform

REPORTS_PER_SECOND = 4
ATOMIC = 4000  # bytes: a pipe write up to PIPE_BUF (4096 on Linux) is never torn between workers
HELD = 5.0  # seconds a worker retries a message the parent must get (start, phase)


def throttled(sink: Callable[[dict], None]) -> Callable[[dict], None]:
    """``sink`` for at most REPORTS_PER_SECOND reports; the others are dropped."""
    last = -1.0

    def send(report: dict) -> None:
        nonlocal last
        now = time.monotonic()
        if now - last >= 1 / REPORTS_PER_SECOND:
            last = now
            sink(report)

    return send


@dataclass
class Worker:
    """A worker process's settings, from the pool's initializer."""

    threads: int
    pipe: Connection
    progress: bool
    modules: int = 0  # len(sys.modules) when the threads were last set

    def send(self, message: tuple, *, must: bool = False) -> None:
        """Write ``message`` to the parent; a message it ``must`` get is retried while the
        pipe is full (the parent reads it several times a second), the rest dropped."""
        data = pickle.dumps(message)
        if len(data) > ATOMIC:
            return
        give_up = time.monotonic() + (HELD if must else 0)
        while True:
            try:
                self.pipe.send_bytes(data)
                return
            except BlockingIOError:
                if time.monotonic() > give_up:
                    return
                time.sleep(0.01)
            except OSError:  # the parent is gone: the fit goes on
                return

    def limit_threads(self) -> None:
        """Set the threads of libraries imported since the last time (a model's import of
        torch or numba comes with new modules); threadpoolctl costs ~5 ms, not each task."""
        if len(sys.modules) != self.modules:
            threads.set_threads(self.threads)
            self.modules = len(sys.modules)


_worker: Worker | None = None


def start(n_threads: int, plugin_files: dict[str, str], pipe: Connection, progress: bool) -> None:
    """The pool's initializer: threads first (before a model imports numba or torch), then the
    folder plugins the parent loaded, under the same names."""
    global _worker
    threads.set_environment(n_threads, numba=True)
    os.set_blocking(pipe.fileno(), False)
    _worker = Worker(n_threads, pipe, progress)
    _worker.limit_threads()
    _worker.send(("hello", os.getpid()), must=True)
    from slipbench.engine.registry import import_plugin_file

    for path in plugin_files.values():
        try:
            import_plugin_file(path)
        # its cells fail with the error when it is used; a sys.exit at import must not end
        # the worker either (pebble would start another, forever)
        except (Exception, SystemExit):  # noqa: BLE001
            pass


def run(task: int, job: bytes) -> list[Result]:
    """One task in a worker: ``job`` is a pickled :class:`~slipbench.engine.fitting.Job`,
    unpickled here, after the parent knows this process runs ``task`` (unpickling imports the
    plugin, whose code may end the process)."""
    worker = _worker
    assert worker is not None, "run() is for pool workers set up by start()"
    worker.send(("start", task, os.getpid()), must=True)
    loaded = pickle.loads(job)
    worker.limit_threads()
    sink = throttled(lambda r: worker.send(("report", r))) if worker.progress else None
    with listening(sink):
        return perform(loaded, lambda phase: worker.send(("phase", task, phase), must=True))


def received(pipe: Connection) -> list[tuple[Any, ...]]:
    """In the parent: every message waiting in the pipe."""
    out = []
    while pipe.poll():
        out.append(pickle.loads(pipe.recv_bytes()))
    return out
