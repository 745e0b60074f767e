"""The detector contract: BaseDetector and its live scorer, Streamer (protocols: ``slipbench.protocol``).

Detectors follow scikit-learn's estimator conventions: ``__init__`` stores keyword
hyperparameters under their own names and nothing else; fitted state ends in ``_``;
``get_params``/``set_params``/``clone`` come from the base class. The base class owns ``fit``,
``predict_proba`` and ``predict``: it validates parameters and input once, then calls the
plugin's ``_fit`` and ``_predict_proba``, which never re-check.
"""

from __future__ import annotations

import copy
import importlib
import inspect
import json
import math
import os
import re
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from importlib.metadata import entry_points
from typing import Any, ClassVar

import numpy as np

from slipbench.atomic import atomic_file
from slipbench.errors import DetectorOutputError, PluginError, UsageError
from slipbench.params import Parameterized
from slipbench.vocabulary import MIN_WINDOW

DETECTOR_GROUP = "slipbench.detectors"  # the entry-point group of detector plugins

# What a detector may read (its ``inputs``): windows of the paper's univariate signal s, or of the
# raw channels the engine standardized; and the shape of each kind's windows.
INPUT_SHAPES = {
    "univariate": "(n_windows, window_length)",
    "channels": "(n_windows, window_length, n_channels)",
}
_KIND_OF_NDIM = {2: "univariate", 3: "channels"}


class NotFittedError(UsageError):
    """predict was called before fit."""


# Where a fit's progress goes (BaseDetector.report_progress): set by whoever runs the fit, for
# example the engine, which shows it beside its bar; None when nobody listens.
ProgressSink = Callable[[dict[str, Any]], None]
_progress_sink: ProgressSink | None = None


@contextmanager
def listening(sink: ProgressSink | None) -> Iterator[None]:
    """Send every :meth:`BaseDetector.report_progress` made in this process inside the block to
    ``sink`` (one dict per report: ``detector``, ``step``, ``total``, ``unit`` and the figures)."""
    global _progress_sink
    previous, _progress_sink = _progress_sink, sink
    try:
        yield
    finally:
        _progress_sink = previous


# ----------------------------------------------------------------------------- detectors
def plugin_id(cls: type) -> str:
    """A plugin class's id: the name the registry gave it, else its class name in kebab case
    (``WaveletSVM`` -> ``wavelet-svm``) for a class used without the registry."""
    stamped = cls.__dict__.get("name")
    if stamped:
        return stamped
    return re.sub(r"(?<=[a-z0-9])(?=[A-Z])|(?<=[A-Z])(?=[A-Z][a-z])", "-", cls.__name__).lower()


def too_few_windows(cls: type[BaseDetector], y: np.ndarray) -> str:
    """Why detector class ``cls`` cannot fit on labels ``y`` (n_windows,): a class has fewer
    windows than its :attr:`~BaseDetector.min_class_windows`; "" where it can."""
    need = cls.min_class_windows
    counts = {"slip": int((y == 1).sum()), "non-slip": int((y == 0).sum())}
    if min(counts.values()) >= need:
        return ""
    held = " and ".join(f"{n} {name}" for name, n in counts.items())
    return (
        f"{plugin_id(cls)} needs at least {need} training windows of each class; the training "
        f"side holds {held}"
    )


@dataclass(frozen=True)
class FitJob:
    """One model's training data for :meth:`BaseDetector.fit_lockstep`: :meth:`BaseDetector.fit`'s
    arguments."""

    x: Any
    y: Any
    seed: int = 0
    sampling_rate: float = 1000.0
    groups: Any = None


class BaseDetector(Parameterized):
    """A binary slip detector on windows of the univariate signal or of the raw channels.

    Subclasses define ``__init__`` with keyword hyperparameters only, declare their
    constraints in ``_parameter_constraints`` (parameter -> Interval/Options/...), and implement
    ``_fit`` and ``_predict_proba``. Their id is the name they are registered under.

    Optional capabilities a subclass may declare (class attributes, defaults below):
    ``requires``, modules it imports that slipbench does not install (``slipbench list`` reports
    the absent ones) with ``install_hint``, how to install them; ``check_params``,
    hyperparameters that make the conformance checks fast (few epochs, few kernels), applied to
    a clone by :mod:`slipbench.testing`; ``data_files``, files (or folders) the plugin reads,
    relative to the folder of the module that declares them, which are part of its code
    identity (cache keys); ``reference``, True on the one detector that is the baseline every
    table compares against (``slipbench list`` says which); ``lockstep``, that
    :meth:`fit_lockstep` trains many models together (the class implements
    ``_fit_lockstep``); ``min_class_windows``, the fewest training windows of each class
    ``fit`` can learn from (a network that holds some out to validate on needs 2): planning
    skips a cell with fewer, saying so (:func:`too_few_windows`), and ``fit`` refuses them; and
    the classmethod :meth:`benchmark`.

    ``inputs`` says which windows the detector reads: ``("univariate",)`` (the default), windows
    (n_windows, window_length) of the paper's signal s_t = ||a_t|| - ||a_{t-1}||;
    ``("channels",)``, windows (n_windows, window_length, n_channels) of the raw channels, each
    standardized by the engine with the training side's statistics; or both,
    ``("univariate", "channels")``, which the engine may run either way (``--input``). The base
    class refuses windows of a kind the detector does not declare, so ``_fit`` and
    ``_predict_proba`` see only declared kinds.
    """

    name: ClassVar[str] = ""  # set by the registry on each class it loads: the plugin's id
    requires: ClassVar[tuple[str, ...]] = ()  # optional modules, e.g. ("aeon",)
    install_hint: ClassVar[str | None] = None  # e.g. "pip install 'slipbench[minirocket]'"
    check_params: ClassVar[dict[str, Any]] = {}  # fast settings for the conformance checks
    data_files: ClassVar[tuple[str, ...]] = ()  # e.g. ("weights.json",): hashed into cache keys
    inputs: ClassVar[tuple[str, ...]] = ("univariate",)  # or ("univariate", "channels"), ...
    reference: ClassVar[bool] = False  # True on the baseline every table compares against
    lockstep: ClassVar[bool] = False  # trains many models together: see fit_lockstep
    min_class_windows: ClassVar[int] = 1  # fewest training windows of each class fit can use

    # -- input checks
    def _check_x(self, x: Any) -> np.ndarray:
        """``x`` as C-contiguous float32 windows of a kind this detector declares in
        :attr:`inputs`, or a UsageError naming the shape and the declared inputs."""
        x = np.asarray(x, dtype=np.float32)
        kind = _KIND_OF_NDIM.get(x.ndim)
        if kind not in self.inputs:
            raise UsageError(_undeclared(type(self), x.shape))
        if x.shape[0] == 0:
            raise UsageError("no windows given")
        if x.shape[1] < MIN_WINDOW:
            raise UsageError(f"windows must have at least {MIN_WINDOW} samples, got {x.shape[1]}")
        if x.ndim == 3 and x.shape[2] == 0:
            raise UsageError(f"windows of channels need at least one channel, got shape {x.shape}")
        bad = ~np.isfinite(x)
        if bad.any():
            at = np.argwhere(bad)[0]
            where = f"window {at[0]}, sample {at[1]}" + (
                f", channel {at[2]}" if x.ndim == 3 else ""
            )
            raise UsageError(f"windows contain NaN or infinity (first at {where})")
        return np.ascontiguousarray(x)

    def _check_fitted(self) -> None:
        if not getattr(self, "window_length_", None):
            raise NotFittedError(
                f"this {type(self).__name__} is not fitted yet; call fit before predict"
            )

    # -- the public API
    def fit(
        self,
        x: Any,
        y: Any,
        *,
        sampling_rate: float = 1000.0,
        seed: int = 0,
        groups: Any = None,
    ) -> BaseDetector:
        """Fit on windows ``x`` and labels ``y`` (n_windows,) (1 = slip).

        ``x`` is (n_windows, window_length) univariate windows, or (n_windows, window_length,
        n_channels) windows of channels for a detector whose :attr:`inputs` declare
        ``"channels"``; ``window_length_`` and ``n_channels_`` (0 for univariate windows) record
        which, and ``predict_proba`` takes only that kind and channel count.

        ``sampling_rate`` (Hz) lets spectral detectors speak in hertz; ``seed`` drives every
        random choice the detector makes; ``groups`` (n_windows,), optional, is the trial of
        each window (the engine always gives it), passed on to a ``_fit`` that takes a
        ``groups`` keyword, so that a held-out validation part can be whole trials.
        """
        fit_args = self._checked_fit_args(x, y, sampling_rate, groups)
        self._fit(*fit_args[:2], seed, **fit_args[2])
        return self

    def _checked_fit_args(
        self, x: Any, y: Any, sampling_rate: float, groups: Any
    ) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
        """:meth:`fit`'s checks; sets ``sampling_rate_``, ``window_length_`` and ``n_channels_``
        and returns ``_fit``'s x, y and keywords (``groups`` where ``_fit`` takes it)."""
        self.validate_params()
        x = self._check_x(x)
        y = np.asarray(y)
        if y.shape != (x.shape[0],):
            raise UsageError(f"labels must have shape ({x.shape[0]},), got {y.shape}")
        if not np.isin(y, (0, 1)).all():
            raise UsageError("labels must be 0 (no slip) or 1 (slip)")
        if len(np.unique(y)) < 2:
            raise UsageError(
                f"training data holds only class {int(y[0])}; a detector needs slip and non-slip windows"
            )
        if few := too_few_windows(type(self), y):
            raise UsageError(few)
        if not (np.isfinite(sampling_rate) and sampling_rate > 0):
            raise UsageError(f"sampling_rate must be a positive number of Hz, got {sampling_rate}")
        self.sampling_rate_ = float(sampling_rate)
        self.window_length_ = x.shape[1]
        self.n_channels_ = x.shape[2] if x.ndim == 3 else 0
        trials = None if groups is None else np.asarray(groups)
        if trials is not None and trials.shape != (x.shape[0],):
            raise UsageError(f"groups must have shape ({x.shape[0]},), got {trials.shape}")
        takes_groups = "groups" in inspect.signature(self._fit).parameters
        return x, y.astype(np.int8), ({"groups": trials} if takes_groups else {})

    @classmethod
    def fit_lockstep(cls, detectors: list[BaseDetector], jobs: list[FitJob]) -> list[BaseDetector]:
        """Fit each of ``detectors`` (instances of this class, e.g. clones with their own
        hyperparameters) on its own :class:`FitJob`, and return them fitted exactly as
        ``detector.fit(job.x, job.y, sampling_rate=job.sampling_rate, seed=job.seed,
        groups=job.groups)`` would: the same checks, the same fitted attributes, the same
        weights (to float tolerance). The capability :attr:`lockstep` says whether the class
        trains many models together (faster); without it they are fitted one after another.

        A plugin declares ``lockstep = True`` and implements the classmethod
        ``_fit_lockstep(detectors, data)``: ``data`` is, for each detector, ``_fit``'s
        arguments (x, y, seed), checked, plus its keywords (``groups``) where ``_fit`` takes
        them; it fits every detector as its ``_fit`` would, grouping those it can train
        together itself (which share hyperparameters, window length, device)."""
        if len(detectors) != len(jobs):
            raise UsageError(f"{len(detectors)} detectors for {len(jobs)} fit jobs")
        for det in detectors:
            if type(det) is not cls:
                raise UsageError(f"{cls.__name__}.fit_lockstep got a {type(det).__name__}")
        args = [
            d._checked_fit_args(j.x, j.y, j.sampling_rate, j.groups)
            for d, j in zip(detectors, jobs)
        ]
        data = [(x, y, j.seed, kw) for (x, y, kw), j in zip(args, jobs)]
        if cls.lockstep:
            cls._fit_lockstep(detectors, data)
        else:
            for det, (x, y, seed, kw) in zip(detectors, data):
                det._fit(x, y, seed, **kw)
        return detectors

    @classmethod
    def prepare(cls, say: Callable[[str], None]) -> None:
        """Work done once per machine before a run's workers start, such as compiling kernels
        that every worker would otherwise compile at once; a class that does some says so
        first through ``say`` (one line: what, and about how long). By default nothing."""

    @classmethod
    def prepare_ahead(cls, say: Callable[[str], None]) -> None:
        """Begin :meth:`prepare`'s work beside this process and return at once (a class whose
        work runs in a child process): the engine calls it before the dataset is read or
        simulated, then :meth:`prepare`, which waits for it, before the workers start. Work
        begun that the run turns out not to need must end with this process. By default
        nothing (:meth:`prepare` does it all)."""

    def lockstep_key(self, window_length: int) -> str:
        """What models of a :attr:`lockstep` class must share to train together: by default
        their hyperparameters and window length (samples). The engine sends cells whose
        detectors (of one class) give one key, on one input, to a worker as one task that fits
        them through :meth:`fit_lockstep`; a class whose training shares more (a device, a
        sampling rate) adds it here."""
        return repr((sorted(self.get_params().items()), int(window_length)))

    @classmethod
    def _fit_lockstep(cls, detectors: list[BaseDetector], data: list[tuple]) -> None:
        """What a class that declares :attr:`lockstep` implements (see :meth:`fit_lockstep`)."""
        raise NotImplementedError

    def predict_proba(self, x: Any) -> np.ndarray:
        """Probability of slip per window, shape (n_windows,), for windows of the kind, length
        and channel count the detector was fitted on."""
        self._check_fitted()
        x = self._check_x(x)
        channels = getattr(self, "n_channels_", 0)  # set by fit; absent in files of older versions
        if (x.shape[2] if x.ndim == 3 else 0) != channels:
            raise UsageError(f"fitted on {_kind_words(channels)}, got windows of shape {x.shape}")
        if x.shape[1] != self.window_length_:
            raise UsageError(
                f"fitted on windows of {self.window_length_} samples, got {x.shape[1]}"
            )
        return self._checked_output(self._predict_proba(x), len(x))

    def _checked_output(self, scores: Any, n: int) -> np.ndarray:
        """The plugin's scores as (n,) float64, or DetectorOutputError saying what is wrong:
        a wrong number would otherwise pass as a result (NaN scores read as 50 % accuracy)."""
        who = f"detector {plugin_id(type(self))!r}"
        try:
            scores = np.asarray(scores, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise DetectorOutputError(
                f"{who} returned scores that are not numbers: {exc}"
            ) from None
        if scores.shape != (n,):
            raise DetectorOutputError(
                f"{who} returned scores of shape {scores.shape} for {n} windows; expected ({n},)"
            )
        bad = ~np.isfinite(scores)
        if bad.any():
            raise DetectorOutputError(
                f"{who} returned {int(bad.sum())} non-finite scores (NaN or infinity) of {n}, "
                f"first at window {int(np.argmax(bad))}"
            )
        outside = (scores < 0) | (scores > 1)
        if outside.any():
            raise DetectorOutputError(
                f"{who} returned {int(outside.sum())} scores outside [0, 1] of {n} "
                f"(from {scores.min():g} to {scores.max():g}); predict_proba gives probabilities"
            )
        return scores

    def report_progress(
        self, step: int, total: int | None = None, *, unit: str = "epoch", **figures: float
    ) -> None:
        """Say how far a long ``_fit`` has come, e.g. ``self.report_progress(epoch, max_epochs,
        loss=validation_loss)`` after each epoch; ``slipbench evaluate`` shows the latest report
        beside its bar. Costs a function call when nobody listens (:func:`listening`)."""
        sink = _progress_sink
        if sink is not None:
            sink(
                {
                    "detector": plugin_id(type(self)),
                    "step": int(step),
                    "total": None if total is None else int(total),
                    "unit": unit,
                    **{k: float(v) for k, v in figures.items()},
                }
            )

    def predict(self, x: Any) -> np.ndarray:
        """1 where the detector calls slip, shape (n_windows,)."""
        return (self.predict_proba(x) >= 0.5).astype(np.int8)

    # -- streaming: a robot's control loop
    def streamer(self, hop: int, threshold: float = 0.5) -> Streamer:
        """A causal stream through this fitted detector (see :mod:`slipbench.base`).

        ``stream = detector.streamer(hop)``; ``scores, decisions = stream.push(samples)`` takes any
        number of new samples of the univariate signal (of every channel, (k, n_channels_), for
        a detector fitted on channels) and gives one score and one 0/1 decision
        (score >= ``threshold``) per completed hop: scores at samples ``window - 1``,
        ``window - 1 + hop``, ..., each seeing only the last ``window_length_`` samples. ``hop``
        is in samples, 1 <= hop <= ``window_length_``.
        """
        self._check_fitted()
        return self._streamer(check_hop(hop, self.window_length_), check_threshold(threshold))

    def _streamer(self, hop: int, threshold: float) -> Streamer:
        """What :meth:`streamer` returns once it has checked its arguments: by default
        ``predict_proba`` over the sliding window; override with a faster :class:`Streamer`."""
        return Streamer(self, hop, threshold)

    # -- persistence without pickle: parameters as JSON, fitted attributes as plain arrays, a
    # fitted scikit-learn estimator through skops (its own format, types checked before loading)
    def save(self, path: str | os.PathLike) -> None:
        """Write the fitted detector to ``path`` (an .npz that ``np.load(allow_pickle=False)``
        reads). Fitted attributes must be arrays, numbers, strings or tuples/lists of them, or
        scikit-learn estimators (a pipeline too) made of scikit-learn's own types (trees,
        forests, boosting, neighbours, linear models, scalers: the types skops trusts and
        :data:`SKLEARN_STATE_TYPES`), numpy's and Python's; such an estimator is stored as skops
        bytes, never pickled."""
        self._check_fitted()
        arrays, kinds = {}, {}
        for key, value in vars(self).items():
            if key.endswith("_") and not key.startswith("_"):
                if _is_estimator(value):
                    arrays[key], kinds[key] = _estimator_bytes(self, key, value), SKOPS
                    continue
                arrays[key] = np.asarray(value)
                if arrays[key].dtype == object:
                    raise UsageError(
                        f"cannot save {type(self).__name__}: fitted attribute {key!r} holds a "
                        f"{type(value).__name__}, not an array, number, string or "
                        "scikit-learn estimator"
                    )
                kinds[key] = (
                    type(value).__name__
                    if isinstance(value, (tuple, list, np.ndarray))
                    else "scalar"
                )
        cls = type(self)
        meta = {
            "format": "slipbench-detector-1",
            "class": f"{cls.__module__}:{cls.__qualname__}",
            "name": plugin_id(cls),
            "params": _encode(self.get_params()),
            "kinds": kinds,
        }
        # a unique temporary name: two processes may save the same model key at once
        with atomic_file(path) as f:
            np.savez(f, __meta__=np.array(json.dumps(meta)), **arrays)  # type: ignore[arg-type]  # keys end in "_": none is savez's allow_pickle

    @classmethod
    def load(cls, path: str | os.PathLike) -> BaseDetector:
        """Read a detector written by :meth:`save`. ``SomeDetector.load`` insists on that class;
        ``BaseDetector.load`` finds the saved class among modules already imported and the
        modules of installed detector plugins (entry points), never importing anything else."""
        try:
            with np.load(path, allow_pickle=False) as f:
                meta = json.loads(str(f["__meta__"]))
                arrays = {k: f[k] for k in f.files if k != "__meta__"}
        except (OSError, ValueError, KeyError) as exc:
            raise UsageError(f"{path} is not a saved slipbench detector: {exc}") from exc
        if cls is BaseDetector:
            cls = _saved_class(meta["class"], path)
        elif meta["class"].rsplit(":", 1)[-1] != cls.__qualname__:
            raise UsageError(
                f"{path} holds a {meta['class']} ({meta['name']!r}), not a {cls.__name__}"
            )
        detector = cls(**_decode(meta["params"]))
        for key, value in arrays.items():
            kind = meta["kinds"][key]
            detector.__dict__[key] = (
                _estimator_from(value, key, path)
                if kind == SKOPS
                else value.item()
                if kind == "scalar"
                else value
                if kind == "ndarray"
                else (tuple if kind == "tuple" else list)(value.tolist())
            )
        return detector

    def fitted_choices(self) -> dict[str, Any]:
        """What fitting chose that a reader of the results should see (plain JSON values): a
        band in Hz as ``band_hz`` [low, high], a ``threshold``, ``epochs`` (the epochs an
        iterative fit ran; also its own column of the row), .... Stored in each result row and
        shown by the report; a band at 0 Hz or reaching Nyquist is flagged there."""
        return {}

    def overrides(self) -> dict[str, tuple[Any, str]]:
        """The declared parameters this fit ran with another value than the one asked:
        ``{name: (the value that ran, why)}`` (plain JSON values), e.g. ``{"band": ([0.6, 2.16],
        "above Nyquist 2.4 Hz")}``; none by default. The engine makes each a warning of the
        row and keeps it in ``fitted`` (``"overrides"``); reports show the value that ran,
        beside the one asked (:func:`slipbench.store.columns.overridden`)."""
        return {}

    @classmethod
    def benchmark(cls, length: int, seconds: float, seed: int = 0) -> Any:
        """Optional: the detector's own speed figures (a DataFrame) against a reference timed in
        the same run, shown by ``slipbench bench``; None when it has none."""
        return None

    # -- what plugins implement
    def _fit(self, x: np.ndarray, y: np.ndarray, seed: int) -> None:
        """The plugin's training, called by :meth:`fit` after every check: ``x`` (n_windows,
        window_length) finite float32, or (n_windows, window_length, n_channels) where the
        detector declares ``"channels"``, ``y`` (n_windows,) int8 0/1 holding both classes,
        ``seed`` an int for every random choice (drawn from the run's stream ``detector``).
        Store what it learns in attributes ending in ``_``; ``sampling_rate_`` (Hz),
        ``window_length_`` and ``n_channels_`` are already set. Returns nothing."""
        raise NotImplementedError

    def _predict_proba(self, x: np.ndarray) -> np.ndarray:
        """The plugin's scoring, called by :meth:`predict_proba` (and the default streamer)
        after every check: ``x`` (n_windows, ``window_length_``) finite float32, or (n_windows,
        ``window_length_``, ``n_channels_``) for a detector fitted on channels. Returns
        (n_windows,) probabilities of slip; a wrong shape, a non-finite value or one outside
        [0, 1] fails the cell with a DetectorOutputError naming the detector."""
        raise NotImplementedError


def _undeclared(cls: type[BaseDetector], shape: tuple[int, ...]) -> str:
    """Why windows of ``shape`` are refused: the shapes ``cls`` declares, and what would take them."""
    words = {"univariate": "univariate windows", "channels": "windows of channels"}
    takes = " or ".join(f"{words[k]} {INPUT_SHAPES[k]}" for k in cls.inputs if k in words)
    kind = _KIND_OF_NDIM.get(len(shape))
    hint = f"; {words[kind]} need a detector that declares {kind!r} in its inputs" if kind else ""
    return (
        f"detector {plugin_id(cls)!r} takes {takes or 'no known input'} (inputs: "
        f"{', '.join(cls.inputs)}), got an array of shape {shape}{hint}"
    )


def _kind_words(n_channels: int) -> str:
    """The windows a detector was fitted on, in words: its ``n_channels_`` (0: univariate)."""
    if not n_channels:
        return f"univariate windows {INPUT_SHAPES['univariate']}"
    return f"windows of {_channels(n_channels)} (n_windows, window_length, {n_channels})"


def _channels(n: int) -> str:
    return f"{n} channel{'' if n == 1 else 's'}"


def _saved_class(target: str, path: Any) -> type:
    """The class ``module:qualname`` of a saved detector, from an imported module or an
    installed plugin's module."""
    module_name, _, qualname = target.partition(":")
    module = sys.modules.get(module_name)
    if module is None and (
        module_name.startswith("slipbench.")
        or any(
            ep.value.partition(":")[0] == module_name for ep in entry_points(group=DETECTOR_GROUP)
        )
    ):
        module = importlib.import_module(module_name)
    obj = module
    for part in qualname.split(".") if module is not None else ():
        obj = getattr(obj, part, None)
    if not (isinstance(obj, type) and issubclass(obj, BaseDetector)):
        raise UsageError(
            f"{path} holds a {target}, which is not an installed detector; load its plugin first "
            "(a plugin folder: slipbench.engine.registry.add_plugin_folder) or call TheClass.load"
        )
    return obj


SKOPS = "skops"  # the kind of a fitted attribute saved by skops.io

# scikit-learn's own types that fitted trees, forests, boosting and neighbours hold, which skops
# does not trust by default (they are not estimators): trusted here by name. skops builds each
# from plain arrays and numbers (never pickle); a distance that runs a Python function
# (PyFuncDistance) is left out. Private module paths move between scikit-learn versions:
# tests/plugins/test_estimator_state.py imports every name from the installed scikit-learn.
SKLEARN_STATE_TYPES: tuple[str, ...] = (
    # decision trees, and every forest or boosting of them (random forest, extra trees,
    # gradient boosting, AdaBoost, bagging, isolation forest)
    "sklearn.tree._tree.Tree",
    # histogram gradient boosting
    "sklearn.ensemble._hist_gradient_boosting.predictor.TreePredictor",
    # nearest neighbours: their search trees and the distances they measure with
    "sklearn.neighbors._kd_tree.KDTree",
    "sklearn.neighbors._ball_tree.BallTree",
    *(
        f"sklearn.metrics._dist_metrics.{name}Distance{bits}"
        for name in ("Euclidean", "SEuclidean", "Manhattan", "Chebyshev", "Minkowski")
        for bits in (64, 32)
    ),
    # voting and stacking ensembles keep their fitted members in a Bunch (a dict)
    "sklearn.utils._bunch.Bunch",
)


def _is_estimator(value: Any) -> bool:
    """Whether ``value`` is a scikit-learn estimator (imported only where sklearn already is)."""
    base = sys.modules.get("sklearn.base")
    return base is not None and isinstance(value, base.BaseEstimator)


def _untrusted(data: bytes) -> list[str]:
    """The types in skops bytes that neither skops (its own check, which reads the file's
    schema without running anything) nor :data:`SKLEARN_STATE_TYPES` trusts."""
    import skops.io

    return [t for t in skops.io.get_untrusted_types(data=data) if t not in SKLEARN_STATE_TYPES]


def _untrusted_advice(untrusted: list[str]) -> str:
    """What to do about ``untrusted`` types: scikit-learn's own ones not listed as safe state,
    or the plugin's own (or another library's) types."""
    own = [t for t in untrusted if t.split(".", 1)[0] == "sklearn"]
    if len(own) == len(untrusted):
        return (
            "scikit-learn types slipbench does not list as safe state "
            "(slipbench.base.SKLEARN_STATE_TYPES); use a model made of listed ones (trees, "
            "forests, boosting, neighbours, linear models, pipelines, scalers), or keep its "
            "fitted arrays as attributes ending in '_' and rebuild it in _predict_proba"
        )
    return (
        "types that are not scikit-learn's own; keep their fitted arrays as attributes "
        "ending in '_' (a custom transformer's mean_, say) and apply them in _predict_proba, "
        "or use scikit-learn's own types in their place"
    )


def _estimator_bytes(detector: BaseDetector, key: str, value: Any) -> np.ndarray:
    """A fitted estimator as skops bytes (uint8), refused where loading it would need a type
    that neither skops nor :data:`SKLEARN_STATE_TYPES` trusts."""
    import skops.io

    data = skops.io.dumps(value)
    untrusted = _untrusted(data)
    if untrusted:
        raise UsageError(
            f"cannot save {type(detector).__name__}: fitted attribute {key!r} "
            f"({type(value).__name__}) holds types skops does not trust, so it could not be "
            f"loaded without running their code: {', '.join(untrusted)}; these are "
            + _untrusted_advice(untrusted)
        )
    return np.frombuffer(data, dtype=np.uint8)


def _estimator_from(value: np.ndarray, key: str, path: Any) -> Any:
    """The estimator in skops bytes, after the check that every type in it is trusted (by
    skops or by :data:`SKLEARN_STATE_TYPES`)."""
    import skops.io

    data = value.tobytes()
    try:
        untrusted = _untrusted(data)
    except Exception as exc:  # noqa: BLE001 - whatever a damaged file makes skops raise
        raise UsageError(
            f"{path}: fitted attribute {key!r} is not readable skops data: {exc}"
        ) from exc
    if untrusted:
        raise UsageError(
            f"{path}: fitted attribute {key!r} holds types skops does not trust: "
            f"{', '.join(untrusted)}; not loaded (loading would run their code)"
        )
    return skops.io.loads(data, trusted=list(SKLEARN_STATE_TYPES))


def _encode(value: Any) -> Any:
    """Parameters -> JSON, keeping tuples apart from lists (``clone`` of a loaded detector must
    equal the original's)."""
    if isinstance(value, dict):
        return {k: _encode(v) for k, v in value.items()}
    if isinstance(value, (tuple, list)):
        items = [_encode(v) for v in value]
        return {"__tuple__": items} if isinstance(value, tuple) else items
    return value.item() if isinstance(value, np.generic) else value


def _decode(value: Any) -> Any:
    if isinstance(value, dict):
        return (
            tuple(_decode(v) for v in value["__tuple__"])
            if "__tuple__" in value
            else {k: _decode(v) for k, v in value.items()}
        )
    return [_decode(v) for v in value] if isinstance(value, list) else value


def clone(detector: BaseDetector) -> BaseDetector:
    """A new, unfitted detector with the same hyperparameters."""
    return type(detector)(**copy.deepcopy(detector.get_params()))


# ----------------------------------------------------------------------------- live scoring
# Causal scoring of a live signal: :class:`Streamer` and its batch twin :func:`stream_scores`.
#
# A robot's control loop feeds a fitted detector the univariate signal s_t (or, for a detector
# fitted on channels, every channel's sample) as it arrives and gets one score and one 0/1
# decision per hop, each from the last ``window`` samples only. Scores fall on
# the samples ``window - 1, window - 1 + hop, window - 1 + 2 hop, ...`` (indices counted from the
# first sample pushed): the score at sample e is the detector's probability for the window
# ``s[e - window + 1 : e + 1]``, what ``predict_proba`` gives that window (to float32 rounding
# where a detector's arithmetic depends on the batch: wavelet-svm's, by up to 3e-6).
#
# ``detector.streamer(hop)`` (``BaseDetector``) makes one; a detector may return a subclass of
# :class:`Streamer` that overrides :meth:`Streamer._push` for speed (the LSTM does), and it must
# give the same scores as ``predict_proba`` on the same windows.

# The default hop: 10 samples, 10 ms at 1 kHz. Scores at 100 Hz match the 100 Hz - 1 kHz loops of
# grasp controllers, the hop's quantization of a delay (at most 10 ms) is 5 % of the 200 ms
# budget, and a stream costs a tenth of a score per sample.
DEFAULT_HOP = 10

# windows scored by one predict_proba call at most: bounds memory when a whole recording is
# pushed at once (at window 200 a batch is 6.5 MB of float32). It costs no speed: holweg scored
# 192,000 windows of 50 in 0.055 s of CPU in batches of 8192, 0.081 s in one call.
MAX_BATCH = 8192


def check_hop(hop: Any, window: int) -> int:
    """``hop`` as an int in [1, window], or a UsageError naming both values."""
    if isinstance(hop, (bool, np.bool_)) or not isinstance(hop, (int, np.integer)):
        raise UsageError(f"hop must be a whole number of samples, got {hop!r}")
    if not 1 <= hop <= window:
        raise UsageError(f"hop must be between 1 and the window ({window} samples), got {hop}")
    return int(hop)


def check_threshold(threshold: Any) -> float:
    """``threshold`` as a float in [0, 1], or a UsageError."""
    try:
        value = float(threshold)
    except (TypeError, ValueError):
        raise UsageError(f"threshold must be a number in [0, 1], got {threshold!r}") from None
    if not 0.0 <= value <= 1.0:
        raise UsageError(f"threshold must be a number in [0, 1], got {threshold!r}")
    return value


class Streamer:
    """One causal stream through a fitted detector; see the module docstring.

    Attributes
    ----------
    window : int, samples per window (the detector's ``window_length_``).
    n_channels : int, channels per sample (the detector's ``n_channels_``); 0 for a stream of
        the univariate signal.
    hop : int, samples between two scores, 1 <= hop <= window.
    threshold : float in [0, 1]; a decision is 1 where score >= threshold (``predict`` uses 0.5).
        May be set at any time.
    n_samples : int, samples pushed since the start (or the last :meth:`reset`).
    n_scores : int, scores given since then.
    """

    def __init__(self, detector: BaseDetector, hop: int, threshold: float = 0.5):
        self.detector = detector
        self.window = int(detector.window_length_)
        self.n_channels = int(getattr(detector, "n_channels_", 0))
        self.hop = check_hop(hop, self.window)
        self.threshold = threshold
        self.reset()

    @property
    def threshold(self) -> float:
        """The decision threshold in [0, 1]: a decision is 1 where score >= threshold. Setting
        it checks the value (UsageError) and applies from the next push."""
        return self._threshold

    @threshold.setter
    def threshold(self, value: float) -> None:
        self._threshold = check_threshold(value)

    def reset(self) -> None:
        """Forget every sample: the next one pushed is sample 0 of a new stream."""
        self.n_samples = 0
        self.n_scores = 0
        # the samples later windows still need: (m,), or (m, n_channels)
        self._tail = np.empty((0, self.n_channels) if self.n_channels else 0, np.float32)

    def push(self, samples: Any) -> tuple[np.ndarray, np.ndarray]:
        """Feed new samples of the signal (a number or a 1-D array, any length, even 0); in a
        stream of channels, an array (k, n_channels) or one sample (n_channels,).

        Returns
        -------
        scores : (n,) float64, one per window completed by these samples, in order.
        decisions : (n,) int8, 1 where score >= threshold.

        Raises UsageError for samples that are not finite numbers, naming the first bad one by
        its index in the stream (and its channel); the stream is then left as it was. A
        detector that returns scores that are not probabilities raises DetectorOutputError, and
        the stream starts anew.
        """
        if self.n_channels:
            x = self._channel_samples(samples)
        else:  # the univariate path, a control loop's: as few numpy calls as can be
            try:
                x = np.asarray(samples, dtype=np.float32)
            except (TypeError, ValueError) as exc:
                raise UsageError(f"samples must be numbers: {exc}") from None
            if x.ndim != 1:
                if x.ndim > 1:
                    raise UsageError(
                        "samples must be a number or a 1-D array of the univariate signal (the "
                        f"detector was fitted on univariate windows), got shape {x.shape}"
                    )
                x = x.reshape(1)
            x = np.ascontiguousarray(x)
            if not _all_finite(x):
                i = int(np.argmin(np.isfinite(x)))
                raise UsageError(
                    f"sample {self.n_samples + i} of the stream is {x[i]} (NaN or infinity)"
                )
        last = self.n_samples + len(x) - 1  # the stream index of the last new sample
        end = self.window - 1 + self.n_scores * self.hop  # where the next score falls
        n = (last - end) // self.hop + 1 if last >= end else 0
        scores = self._push(x, n)
        if not n:
            scores, decisions = _NO_SCORES, _NO_DECISIONS
        else:
            if not _all_probabilities(scores, n):
                try:
                    scores = self.detector._checked_output(
                        scores, n
                    )  # converts, or raises saying what is wrong
                except PluginError:  # DetectorOutputError
                    self.reset()  # the state has moved past samples that n_samples does not count
                    raise
            decisions = (scores >= self._threshold).view(np.int8)
        self.n_samples += len(x)
        self.n_scores += n
        return scores, decisions

    def _channel_samples(self, samples: Any) -> np.ndarray:
        """``samples`` of a stream of channels as a checked, C-contiguous (k, n_channels) float32
        array, or a UsageError naming the shape, or the first non-finite sample and channel."""
        c = self.n_channels
        try:
            x = np.asarray(samples, dtype=np.float32)
        except (TypeError, ValueError) as exc:
            raise UsageError(f"samples must be numbers: {exc}") from None
        if x.shape in ((c,), (0,)):  # one sample, or none
            x = x.reshape(-1, c)
        elif x.ndim != 2 or x.shape[1] != c:
            raise UsageError(
                f"samples must be an array (k, {c}) or one sample ({c},): the detector was fitted "
                f"on {_channels(c)}, got shape {x.shape}"
            )
        x = np.ascontiguousarray(x)
        bad = ~np.isfinite(x)
        if bad.any():
            i, j = np.argwhere(bad)[0]
            raise UsageError(
                f"sample {self.n_samples + i} of the stream, channel {j}, is {x[i, j]} "
                "(NaN or infinity)"
            )
        return x

    def _push(self, x: np.ndarray, n: int) -> np.ndarray:
        """Scores of the ``n`` (maybe 0) windows that the checked float32 samples ``x`` (k,) or
        (k, n_channels) complete.

        The default: the windows cut from the kept tail and ``x``, scored by the detector's
        ``_predict_proba`` (input already checked), up to MAX_BATCH windows per call. An override
        keeps its own state; ``self.n_samples`` and ``self.n_scores`` are updated after it returns.
        """
        data = np.concatenate([self._tail, x]) if len(self._tail) else x
        first = self.n_samples - len(self._tail)  # stream index of data[0]
        scores = np.empty(0)
        if n:
            start = self.n_scores * self.hop - first  # where the next window starts in data
            # the n windows from data[start], hop apart; they end inside data by the count of n
            # (as_strided: sliding_window_view's checks cost more than scoring one window)
            views = np.lib.stride_tricks.as_strided(
                data[start:],
                (n, self.window, *data.shape[1:]),  # (n, window) or (n, window, n_channels)
                (self.hop * data.strides[0], *data.strides),
                writeable=False,
            )
            scores = np.concatenate(
                [
                    self.detector._predict_proba(np.ascontiguousarray(views[i : i + MAX_BATCH]))
                    for i in range(0, n, MAX_BATCH)
                ]
            )
        keep = (self.n_scores + n) * self.hop - first  # the first sample a later window needs
        self._tail = data[keep:].copy()
        return scores


# A control loop pushes a few samples at a time, where each numpy call costs a microsecond or
# more (the 2 µs a sample budget of the LSTM); plain Python is faster on a few numbers.
SMALL = 32
_NO_SCORES, _NO_DECISIONS = np.empty(0), np.empty(0, np.int8)
_NO_SCORES.flags.writeable = _NO_DECISIONS.flags.writeable = (
    False  # shared by every push that completes no window
)


def _all_finite(x: np.ndarray) -> bool:
    return all(map(math.isfinite, x.tolist())) if len(x) <= SMALL else bool(np.isfinite(x).all())


def _all_probabilities(scores: Any, n: int) -> bool:
    """Whether ``scores`` is an (n,) float64 array of numbers in [0, 1] (NaN is not)."""
    if not (isinstance(scores, np.ndarray) and scores.dtype == np.float64 and scores.shape == (n,)):
        return False
    if n <= SMALL:
        return all(0.0 <= v <= 1.0 for v in scores.tolist())
    return bool(((scores >= 0.0) & (scores <= 1.0)).all())


def stream_scores(detector: BaseDetector, signal: Any, hop: int) -> tuple[np.ndarray, np.ndarray]:
    """Every score a fresh stream gives over ``signal``: what pushing the whole signal into
    ``detector.streamer(hop)`` returns, with where each score falls.

    Parameters
    ----------
    detector : a fitted detector.
    signal : (n_samples,) the univariate signal of one recording, or (n_samples, n_channels)
        its channels for a detector fitted on channels.
    hop : samples between scores, 1 <= hop <= window.

    Returns
    -------
    ends : (n_scores,) int64, the index in ``signal`` of each window's last sample:
        ``window - 1 + k * hop``.
    scores : (n_scores,) float64.

    A signal shorter than the window gives no score; it is a UsageError naming both lengths, as
    a window longer than the recording is.
    """
    stream = detector.streamer(hop)
    signal = np.asarray(signal)
    if stream.n_channels and signal.ndim != 2:  # a 1-D signal of n_channels would be one sample
        raise UsageError(
            f"the detector was fitted on {_channels(stream.n_channels)}: the signal must be "
            f"(n_samples, {stream.n_channels}), got shape {signal.shape}"
        )
    if signal.ndim >= 1 and len(signal) < stream.window:
        raise UsageError(
            f"the signal has {len(signal)} samples, fewer than the window ({stream.window} samples)"
        )
    scores, _ = stream.push(signal)
    return stream.window - 1 + stream.hop * np.arange(len(scores), dtype=np.int64), scores


def rate(call: Callable[[], object], units: float, seconds: float) -> float:
    """Units per second of ``call``, repeated for at least ``seconds`` after one warm-up call."""
    call()
    n, start = 0, time.perf_counter()
    while True:
        call()
        n += 1
        elapsed = time.perf_counter() - start
        if elapsed >= seconds:
            return n * units / elapsed


def push_costs(stream: Streamer, pieces: list[np.ndarray]) -> tuple[float, float]:
    """What feeding ``pieces`` one push each costs, robust to other processes on the machine.

    Every push is timed on its own (wall time); the pushes up to the first score (compilation,
    warm-up) are left out, and the median of the pushes that complete a score, and of those
    that only buffer, stands for every push of its kind (a push that waited for another
    process's turn on the core is an outlier, not a cost).

    Returns
    -------
    (µs per sample of the pieces, the median ms of a push that completes a score)
    """
    stream.reset()
    times, scored = np.empty(len(pieces)), np.zeros(len(pieces), bool)
    for i, piece in enumerate(pieces):
        t0 = time.perf_counter()
        scores, _ = stream.push(piece)
        times[i] = time.perf_counter() - t0
        scored[i] = len(scores) > 0
    counted = np.arange(len(pieces)) > np.argmax(scored)
    if not (scored & counted).any():
        raise UsageError(
            f"timing a stream needs pieces that complete at least two scores "
            f"(window {stream.window}, hop {stream.hop}, {sum(map(len, pieces))} samples)"
        )
    total = sum(
        np.median(times[kind]) * kind.sum()
        for kind in (scored & counted, ~scored & counted)
        if kind.any()
    )
    return total / sum(len(p) for p, c in zip(pieces, counted) if c) * 1e6, float(
        np.median(times[scored & counted]) * 1e3
    )


def hop_latency(detector: BaseDetector, signal: Any, hop: int) -> float:
    """The detector's compute time per hop, in ms: the median wall time of the pushes that
    complete a score when ``signal`` ((n_samples,), or (n_samples, n_channels) for a detector
    fitted on channels) is fed one hop at a time, as a control loop would (:func:`push_costs`).
    The streaming protocol reports it against the hop period."""
    x = np.asarray(signal, np.float32)
    return push_costs(detector.streamer(hop), [x[i : i + hop] for i in range(0, len(x), hop)])[1]
