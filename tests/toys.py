"""The toy plugins of the tests, in one place: detectors and protocols as small as the contract
allows, and detectors broken on purpose. Tests use the classes in process, and `source` gives the
text of a plugin file (this module's imports, then the toys) for those that need a plugin
folder, an installed package or a changed plugin; a plugin file holds one plugin and the toys it
derives from, as the registry asks."""

from __future__ import annotations

import ast
import inspect
import os
import signal
import sys
import time
from pathlib import Path

import numpy as np

from slipbench.base import BaseDetector
from slipbench.errors import UsageError
from slipbench.params import Interval
from slipbench.protocol import BaseProtocol, Cell, Layout, Part, Presentation


class Energy(BaseDetector):
    """Mean absolute signal above a training quantile."""

    _parameter_constraints = {"quantile": Interval(float, 0.0, 1.0)}

    def __init__(self, quantile=0.5):
        self.quantile = quantile

    def _fit(self, x, y, seed):
        self.cut_ = float(np.quantile(np.abs(x).mean(axis=1), self.quantile))

    def _predict_proba(self, x):
        return (np.abs(x).mean(axis=1) > self.cut_).astype(float)


class NeedsDep(Energy):
    """Energy that declares a dependency no one has installed."""

    requires = ("no_such_module_slipbench",)


class NanScores(Energy):
    """Returns NaN scores."""

    def _predict_proba(self, x):
        score = super()._predict_proba(x)
        score[::3] = np.nan
        return score


class BigScores(Energy):
    """Returns scores up to 909."""

    def _predict_proba(self, x):
        return super()._predict_proba(x) * 909


class ShortScores(Energy):
    """Returns too few scores."""

    def _predict_proba(self, x):
        return super()._predict_proba(x)[:-1]


class UsageInFit(Energy):
    """Raises a UsageError from fit."""

    def _fit(self, x, y, seed):
        raise UsageError("bad day")


class Constant(BaseDetector):
    """Learns nothing: every window scores 0.5 (called slip at the threshold 0.5); reports the
    one epoch it "ran"."""

    def _fit(self, x, y, seed):
        self.fitted_ = True

    def _predict_proba(self, x):
        return np.full(len(x), 0.5)

    def fitted_choices(self):
        return {"epochs": 1}


class Coin(BaseDetector):
    """Learns nothing: scores drawn at random (from the fit's seed), whatever the window."""

    def _fit(self, x, y, seed):
        self.seed_ = int(seed)

    def _predict_proba(self, x):
        return np.random.default_rng([self.seed_, len(x)]).random(len(x))


class Flaky(BaseDetector):
    """Raises on 5-sample windows, thresholds the mean absolute value otherwise."""

    name = "flaky"

    def __init__(self, cut=1.0):
        self.cut = cut

    def _fit(self, x, y, seed):
        if x.shape[1] == 5:
            raise RuntimeError("diverged on short windows")
        self.level_ = float(np.median(np.abs(x).mean(axis=1)))

    def _predict_proba(self, x):
        return (np.abs(x).mean(axis=1) > self.level_ * self.cut).astype(float)


class Slow(BaseDetector):
    """Sleeps, then thresholds the mean absolute signal (for time-limit and resume tests)."""

    name = "slow"

    def __init__(self, seconds=0.3):
        self.seconds = seconds

    def _fit(self, x, y, seed):
        time.sleep(self.seconds)
        self.cut_ = float(np.median(np.abs(x).mean(axis=1)))

    def _predict_proba(self, x):
        return (np.abs(x).mean(axis=1) > self.cut_).astype(float)


class Doomed(BaseDetector):
    """Killed by the system (as the out-of-memory killer does) on 5-sample windows."""

    def _fit(self, x, y, seed):
        if x.shape[1] == 5:
            os.kill(os.getpid(), signal.SIGKILL)
        self.cut_ = float(np.median(np.abs(x).mean(axis=1)))

    def _predict_proba(self, x):
        return (np.abs(x).mean(axis=1) > self.cut_).astype(float)


class ExitsInFit(Energy):
    """Calls sys.exit(0) in fit, as a script's habit would."""

    def _fit(self, x, y, seed):
        sys.exit(0)


class ExitsInPredict(Energy):
    """Calls sys.exit(3) when it scores windows (a stream too)."""

    def _predict_proba(self, x):
        sys.exit(3)


class ExitsInStream(Energy):
    """Calls sys.exit(0) when a stream through it starts."""

    def streamer(self, hop, threshold=0.5):
        sys.exit(0)


class VanishesInFit(Energy):
    """Ends its process with os._exit(0) in fit: no exception, no cleanup, exit code 0."""

    def _fit(self, x, y, seed):
        os._exit(0)


class VanishesInTest(Energy):
    """Ends its process with os._exit(0) once fitted, when it scores windows."""

    def _predict_proba(self, x):
        os._exit(0)


class Trainer(Energy):
    """Trains for ``epochs`` epochs of ``seconds`` each on windows of ``long_window`` samples
    (one epoch on any other), reporting each epoch and a loss: a long fit to interrupt."""

    def __init__(self, quantile=0.5, epochs=3, seconds=0.2, long_window=0):
        super().__init__(quantile)
        self.epochs, self.seconds, self.long_window = epochs, seconds, long_window

    def _fit(self, x, y, seed):
        epochs = self.epochs if x.shape[1] == self.long_window or not self.long_window else 1
        for epoch in range(1, epochs + 1):
            deadline = time.monotonic() + self.seconds
            while time.monotonic() < deadline:  # in short sleeps, as a training loop runs
                time.sleep(0.01)
            self.report_progress(epoch, epochs, loss=1 / epoch)
        super()._fit(x, y, seed)


class ThreadProbe(Energy):
    """Records the threads numba, the BLAS libraries and torch (where imported) allow while it
    fits, and OMP_NUM_THREADS, in its fitted choices."""

    def _fit(self, x, y, seed):
        import numba
        from threadpoolctl import threadpool_info

        super()._fit(x, y, seed)
        self.seen_ = {
            "numba": numba.get_num_threads(),
            "blas": sorted(
                {p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"}
            ),
            "omp_env": os.environ.get("OMP_NUM_THREADS", ""),
        }
        if "torch" in sys.modules:
            self.seen_["torch"] = sys.modules["torch"].get_num_threads()

    def fitted_choices(self):
        return {"threads": self.seen_}


class TwoCells(BaseProtocol):
    """Window 50 of two Nano17 fingers."""

    layout = Layout(("sensor_type", "sensor_instance"), "window")
    presentation = Presentation("two cells")

    def cells(self, recordings):
        for finger in ("index", "middle"):
            part = (("Nano17", finger),)
            yield Cell(
                key={"sensor_type": "Nano17", "sensor_instance": finger, "window": 50},
                train=Part(part, "train"),
                test=Part(part, "test"),
                window=50,
            )


class TwoWindows(BaseProtocol):
    """Windows of 25 and 50 samples on two Nano17 fingers."""

    layout = Layout(("sensor_type", "sensor_instance"), "window")
    presentation = Presentation(
        "Energy at two window lengths.",
        title="Two windows",
        group="at Window",
        figure="curve",
        x_label="window (samples)",
    )

    def cells(self, recordings):
        for finger in ("index", "middle"):
            part = (("Nano17", finger),)
            for window in (25, 50):
                yield Cell(
                    {"sensor_type": "Nano17", "sensor_instance": finger, "window": window},
                    Part(part, "train"),
                    Part(part, "test"),
                    window,
                )


def source(toy: type) -> str:
    """The text of a plugin file defining ``toy`` and the toys it derives from (bases first),
    under this module's imports."""
    text = Path(__file__).read_text()
    header = [
        ast.get_source_segment(text, node)
        for node in ast.parse(text).body
        if isinstance(node, ast.Import | ast.ImportFrom)
    ]
    classes = [c for c in reversed(toy.__mro__) if c.__module__ == __name__]
    return "\n".join(header) + "\n\n\n" + "\n\n".join(inspect.getsource(c) for c in classes)


class Forever(BaseDetector):
    """A fit that never returns (for the default time limit)."""

    name = "forever"

    def _fit(self, x, y, seed):
        while True:
            time.sleep(3600)

    def _predict_proba(self, x):
        return np.full(len(x), 0.5)


class Spawner(BaseDetector):
    """Starts a child process in a session of its own, writes its pid to ``pid_file``, then
    returns (``hang`` False) or never returns: the child must end with the worker either way."""

    name = "spawner"

    def __init__(self, pid_file="", hang=False):
        self.pid_file = pid_file
        self.hang = hang

    def _fit(self, x, y, seed):
        import subprocess

        child = subprocess.Popen(
            [sys.executable, "-c", "import time; time.sleep(3600)"], start_new_session=True
        )
        with open(self.pid_file, "a") as f:
            f.write(f"{child.pid}\n")
        while self.hang:
            time.sleep(3600)
        self.cut_ = float(np.median(np.abs(x).mean(axis=1)))

    def _predict_proba(self, x):
        return (np.abs(x).mean(axis=1) > self.cut_).astype(float)
