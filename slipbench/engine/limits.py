"""What a command line may ask of the executors, checked before anything heavy is imported
(a mistyped option is refused at once): how many local workers this machine can run, and
whether a ``--scheduler`` names an executor."""

from __future__ import annotations

from pathlib import Path

from slipbench.engine.threads import cores

#: the schedulers named rather than addressed (``--scheduler NAME``); any other value is the
#: address of a dask scheduler
SCHEDULERS = ("slurm", "submitit-local")


#: local worker processes per core beyond which more add only memory and contention (a worker
#: holds its imports and a task's windows; each model gets ``cores // jobs`` threads, at least 1)
JOBS_PER_CORE = 4


def jobs_problem(jobs: int) -> str | None:
    """Why this machine cannot run ``jobs`` local worker processes, or None."""
    most = JOBS_PER_CORE * cores()
    if jobs <= most:
        return None
    return (
        f"more than {most} worker processes ({JOBS_PER_CORE} per core, {cores()} cores "
        "here) add only memory and contention; use a dask scheduler to run on more machines"
    )


def scheduler_problem(scheduler: str) -> str | None:
    """Why ``scheduler`` names no executor, or None: it may name one of
    :data:`SCHEDULERS`, or a dask scheduler by its address (``host:port``,
    ``tcp://host:port``, any scheme dask has) or by its scheduler file (JSON)."""
    if scheduler in SCHEDULERS or Path(scheduler).is_file():
        return None
    try:
        from distributed.comm.addressing import parse_address, parse_host_port
        from distributed.comm.registry import backends
    except ImportError:
        return "a dask scheduler needs dask.distributed: pip install 'slipbench[dask]'"
    named = f", nor one of {', '.join(SCHEDULERS)}" if SCHEDULERS else ""
    try:
        scheme, location = parse_address(scheduler, strict=False)
        if scheme not in backends:
            raise ValueError(f"dask knows no scheme {scheme!r}")
        if scheme != "inproc":
            parse_host_port(location)
    except ValueError as exc:
        return (
            f"not a dask scheduler's address (host:port, tcp://host:port) or scheduler file"
            f"{named} ({exc})"
        )
    return None


#: seconds one model may fit and test in a local worker unless told otherwise (``--cell-timeout``,
#: a run file's ``cell_timeout``; 0: none), so that a plugin whose fit never returns cannot hang
#: a run. Generous: 16x the longest model of the reproduction at scale 0.1 (the LSTM, 451 s;
#: reports/README.md), about 30x at the default scale 0.05, and above the 75 min that model is
#: extrapolated to take at the paper's full size.
DEFAULT_CELL_TIMEOUT = 7200.0


def cell_limit(asked: float | None, jobs: int, scheduler: str | None) -> float | None:
    """The time limit one model gets (seconds; None: none): ``asked`` where given (0: none),
    else :data:`DEFAULT_CELL_TIMEOUT` for local workers. Cells in this process (``jobs`` 0)
    and on a scheduler get no default: nothing there could stop them (a SLURM array has its
    own time limit)."""
    if asked is not None:
        return float(asked) or None
    return DEFAULT_CELL_TIMEOUT if jobs and not scheduler else None


def limit_words(asked: float | None, jobs: int, scheduler: str | None) -> str:
    """The time limit as a line says it where a run starts and in a plan."""
    limit = cell_limit(asked, jobs, scheduler)
    how = "--cell-timeout SECONDS or [run] cell_timeout; 0 for none"
    if limit is None:
        why = (
            "0 given"
            if asked == 0
            else "cells run in this process (--jobs 0)"
            if not jobs and not scheduler
            else "none set for the scheduler's workers"
        )
        return f"time limit: none per model ({why}; {how})"
    default = " (the default)" if asked is None else ""
    return f"time limit: {limit:g} s per model{default}; {how}"
