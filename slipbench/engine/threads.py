"""Threads per model: the engine's one policy, set in every library that trains a model.

A run shares the cores of a machine between the models it fits at once. Each model gets
``cores // models at once`` threads (at least 1), where ``cores`` are those this process may
run on: ``cores // jobs`` in each of ``jobs`` worker processes; all of them in a run in this
process (``jobs=0``, or a script's ``jobs=1`` run in its own process), which fits one model
at a time; on a dask worker, the machine's cores over the threads of every worker of the run
on that machine (workers keep their own ``nthreads``). The number is set in numba, in the
OpenMP and BLAS libraries loaded (threadpoolctl) and in torch: a library left at its default
starts a thread per core in every worker (a batch-1 LSTM fit on a 16-core machine ran 29x
slower with numba's default threads than with one). A worker process also sets the
environment for the libraries a model imports later (``OMP_NUM_THREADS``, ...; in a local
worker ``NUMBA_NUM_THREADS`` too, before numba is imported: on a dask worker, not the run's
own, numba's ceiling is left alone). A run in this process restores the caller's settings
when it ends and leaves the environment alone.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager

# read when a library loads: set where a model may load one later
LOADING = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
# numba's ceiling, read at its import; changed once its threads run, numba refuses to compile
NUMBA = "NUMBA_NUM_THREADS"


def cores() -> int:
    """The cores this process may run on (its CPU affinity: a container's or a CI runner's
    share, not the machine's count)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def share(at_once: int) -> int:
    """Threads per model when ``at_once`` models share this machine's cores."""
    return max(1, cores() // max(1, at_once))


def set_threads(n: int) -> Callable[[], None]:
    """Limit numba, OpenMP, BLAS and torch to ``n`` threads, those of them imported by now;
    returns a function that restores what they had. numba's number is the calling thread's."""
    from threadpoolctl import threadpool_limits

    restores: list[Callable[[], object]] = [threadpool_limits(limits=n).restore_original_limits]
    numba = sys.modules.get("numba")
    if numba is not None:
        before = numba.get_num_threads()
        numba.set_num_threads(min(n, numba.config.NUMBA_NUM_THREADS))  # its ceiling at import
        restores.append(lambda: numba.set_num_threads(before))
    torch = sys.modules.get("torch")
    if torch is not None:
        was = torch.get_num_threads()
        torch.set_num_threads(n)
        restores.append(lambda: torch.set_num_threads(was))

    def restore() -> None:
        for undo in reversed(restores):
            undo()

    return restore


@contextmanager
def limited(n: int) -> Iterator[None]:
    """:func:`set_threads` for the block, the caller's settings restored after it."""
    restore = set_threads(n)
    try:
        yield
    finally:
        restore()


def set_environment(n: int, *, numba: bool) -> None:
    """For libraries a model loads later, in a worker process: torch and OpenMP read
    ``OMP_NUM_THREADS`` when they load; with ``numba``, numba reads ``NUMBA_NUM_THREADS`` at
    its import (set only where it is not imported yet)."""
    for name in LOADING:
        os.environ[name] = str(n)
    if numba and "numba" not in sys.modules:
        os.environ[NUMBA] = str(n)
