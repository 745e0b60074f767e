"""The LSTM's numba kernels compiled once per machine, never by two processes at once.

From an empty numba cache the kernels take over a minute of CPU and most of a GB to compile
(the lockstep kernel alone 68.7 CPU s and 917 MB), and loading them from the cache well under a
second; before this module every worker of ``--jobs 2`` compiled the same kernels at the same
time, and ``slipbench bench`` a third time. Two mechanisms, each for what the other cannot do:

- :func:`ready`: every process compiles or loads the kernels under an exclusive ``flock`` on a
  file in numba's cache folder before its first kernel call, so a second process (a pool worker,
  ``slipbench bench``, another user's run, a dask worker on this machine) waits for the first and
  then loads what it wrote. This alone guarantees "never two at once", whoever starts first,
  and a killed compiler never leaves a stale lock (the kernel drops a dead holder's flock).
- :func:`compile_ahead`: before a run's workers start, the main process has a short-lived child
  compile them (the child's memory goes back to the system when it exits, where the main
  process would keep LLVM's for the whole run), after saying so; the workers then load.
  :func:`start_ahead` starts that child before the dataset is read or simulated (a first run
  does both: they overlap), and :func:`compile_ahead` waits for it.

Whether the kernels are cached is told by a stamp file beside numba's own cache files, written
after every kernel compiled, and named by what numba's cache depends on (these kernel files'
contents, numba, Python, the CPU): deleting the cache folder deletes the stamp with it.
"""

from __future__ import annotations

import atexit
import hashlib
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from slipbench.atomic import folder_lock
from slipbench.errors import EnvironmentFault

# CPU seconds of compiling what evaluate calls (the predict and lockstep groups) from an empty
# cache on the 2-core development machine, shared: 201 at load 4 (benchmarks/
# bench_lstm_compile.py), 298 at load 6-9. What the first line of a run that compiles promises.
COMPILE_CPU_S = 200
LOCK_TIMEOUT_S = 3600.0  # a compile on a machine loaded 4x took over 5 minutes
_KERNEL_FILES = ("lstm_kernels.py", "lstm_lockstep.py", "lstm_simd.py")

# The kernels come in groups, each compiled on first need (_EXERCISE): what a run of
# ``evaluate`` calls (models trained in lockstep, and scoring) apart from the rest, so that its
# first run compiles only what it uses.
_ready: set[str] = set()  # the groups this process has compiled or loaded
_holding = False  # this process holds the lock (an exercise runs)


def cache_folder() -> Path:
    """Where numba caches these kernels (beside the source, NUMBA_CACHE_DIR or the user's
    cache, as numba's own locator decides)."""
    from slipbench.detectors import lstm_kernels

    cache: Any = getattr(lstm_kernels.predict_window, "_cache")  # noqa: B009 (numba's, untyped)
    return Path(cache._cache_path)  # numba's Cache knows its folder from decoration on


def _stamp(group: str) -> Path:
    import llvmlite.binding as llvm
    import numba

    here = Path(__file__).parent
    digest = hashlib.sha256()
    for name in _KERNEL_FILES:
        digest.update((here / name).read_bytes())
    digest.update(f"{numba.__version__} {sys.version} {llvm.get_host_cpu_name()}".encode())
    return cache_folder() / f"slipbench-lstm-{group}-{digest.hexdigest()[:16]}.compiled"


def cached(group: str) -> bool:
    """Whether a process here compiled ``group``'s kernels into the cache (so that loading
    them costs well under a second)."""
    return _stamp(group).exists()


def ready(*groups: str) -> None:
    """Compile ``groups``' kernels, or load them from numba's cache, once per process; under
    the cache folder's lock, so that a second process waits for a compile in flight and then
    loads."""
    global _holding
    if _ready.issuperset(groups):
        return
    todo = [g for g in groups if g not in _ready]
    if _holding:  # called back from an exercise, under the lock already (flock is not reentrant)
        _exercise(todo)
        return
    folder = cache_folder()
    folder.mkdir(parents=True, exist_ok=True)
    with folder_lock(folder, timeout=LOCK_TIMEOUT_S):
        _holding = True
        try:
            _exercise(todo)
        finally:
            _holding = False


def _exercise(groups: list[str]) -> None:
    from slipbench.base import listening

    for group in groups:
        _ready.add(group)  # before exercising: the detector's own calls come back to ready()
        try:
            with listening(None):  # the exercise's epochs are not the run's: not on its bar
                _EXERCISE[group]()
        except BaseException:
            _ready.discard(group)
            raise
        _stamp(group).touch()


class _Child:
    """The child compiling the kernels, started by :func:`start_ahead`: what it printed goes to
    a file (a pipe nobody reads while it compiles could fill and stall it)."""

    def __init__(self) -> None:
        self.started = time.perf_counter()
        self.errors = tempfile.TemporaryFile(mode="w+")
        root = str(Path(__file__).parents[2])  # the slipbench this process imported, not the cwd's
        code = f"import sys; sys.path.insert(0, {root!r}); from slipbench.detectors import lstm; lstm.lstm_compile.ready('predict', 'lockstep')"
        self.process = subprocess.Popen(
            [sys.executable, "-c", code], stdout=subprocess.DEVNULL, stderr=self.errors, text=True
        )
        atexit.register(self.stop)  # a run that ends before waiting for it ends it too

    def wait(self, say: Callable[[str], None]) -> None:
        code = self.process.wait()
        atexit.unregister(self.stop)
        self.errors.seek(0)
        last = (self.errors.read().strip().splitlines() or ["no output"])[-1]
        self.errors.close()
        if code != 0:
            raise EnvironmentFault(
                cache_folder(), f"compiling the LSTM's kernels failed (exit {code}): {last}"
            )
        say(f"lstm: kernels compiled in {time.perf_counter() - self.started:.0f} s")

    def stop(self) -> None:
        if self.process.poll() is None:  # the flock dies with it; numba writes its files whole
            self.process.kill()
            self.process.wait()


_child: _Child | None = None  # the compile start_ahead began and compile_ahead did not wait for


def start_ahead(say: Callable[[str], None]) -> None:
    """Start compiling the kernels a run of ``evaluate`` calls (``lockstep``, ``predict``) in a
    child process where the cache lacks them, and return at once, having said that it does and
    how long it takes; :func:`compile_ahead` waits for it. A child this process never waits for
    is killed when it exits."""
    global _child
    if _child is not None or (cached("lockstep") and cached("predict")):
        return
    say(
        f"lstm: compiling its numba kernels once for this machine, about {COMPILE_CPU_S} CPU s "
        f"(more on a busy machine); later runs load them in under a second"
    )
    _child = _Child()


def compile_ahead(say: Callable[[str], None]) -> None:
    """Compile the kernels a run of ``evaluate`` calls in a child process where the cache lacks
    them (or wait for the one :func:`start_ahead` began), then say how long it took. A child
    that fails is an EnvironmentFault naming its exit code and last line (the workers would
    fail alike)."""
    global _child
    start_ahead(say)
    child, _child = _child, None
    if child is not None:
        child.wait(say)


def exercise_data(n: int = 300) -> tuple[np.ndarray, np.ndarray]:
    """Windows (n, 8) and labels to call the kernels with."""
    x = np.random.default_rng(0).normal(size=(n, 8)).astype(np.float32)
    return x, (np.arange(n) % 2).astype(np.int8)


# Each exercise calls its group's kernels once with the argument types the detector gives them:
# numba compiles each specialization on its first call (or loads it from its cache).
def _predict() -> None:
    """Windows scored one by one, in a block serially and in blocks in parallel."""
    from slipbench.detectors import lstm_kernels as kernels

    x, _ = exercise_data()
    net = kernels.network(0.0, 1.0, kernels.init_params(20, np.random.default_rng(0)))
    for n in (4, 40, 300):
        kernels.predict_proba(x[:n], net)


def _stream() -> None:
    """One window scored alone and a stream pushed (a control loop's kernels)."""
    from slipbench.detectors import lstm_kernels as kernels

    x, _ = exercise_data(1)
    net = kernels.network(0.0, 1.0, kernels.init_params(20, np.random.default_rng(0)))
    kernels.predict_window(x[0], net)
    out, state = np.empty(8), np.zeros((2, 2, 20), np.float32)
    kernels.stream_push(x[0], (0, 8, 4), net, (state, out))


# the groups that train models are exercised through the detector, which registers them
# (lstm.py: this module cannot import it back)
_EXERCISE: dict[str, Callable[[], None]] = {"predict": _predict, "stream": _stream}


def register(group: str, exercise: Callable[[], None]) -> None:
    """Name the function that calls ``group``'s kernels once (see :func:`ready`)."""
    _EXERCISE[group] = exercise
