"""The detector contract: BaseDetector (protocols: ``slipbench.protocol``).

Detectors follow scikit-learn's estimator conventions: ``__init__`` stores keyword
hyperparameters under their own names and nothing else; fitted state ends in ``_``;
``get_params``/``set_params``/``clone`` come from the base class. The base class owns ``fit``,
``predict_proba`` and ``predict``: it validates parameters and input once, then calls the
plugin's ``_fit`` and ``_predict_proba``, which never re-check.
"""

from __future__ import annotations

import copy
import importlib
import json
import os
import re
import sys
from importlib.metadata import entry_points
from typing import Any, ClassVar

import numpy as np

from .atomic import atomic_file
from .errors import PluginError, UsageError
from .params import Parameterized
from .streamer import Streamer, check_hop, check_threshold

DETECTOR_GROUP = "slipbench.detectors"  # the entry-point group of detector plugins

MIN_WINDOW = 5


class NotFittedError(UsageError):
    """predict was called before fit."""


# ----------------------------------------------------------------------------- detectors
def plugin_id(cls: type) -> str:
    """A plugin class's id: the name the registry gave it, else its class name in kebab case
    (``WaveletSVM`` -> ``wavelet-svm``) for a class used without the registry."""
    stamped = cls.__dict__.get("name")
    if stamped:
        return stamped
    return re.sub(r"(?<=[a-z0-9])(?=[A-Z])|(?<=[A-Z])(?=[A-Z][a-z])", "-", cls.__name__).lower()


class BaseDetector(Parameterized):
    """A binary slip detector on windows of a univariate signal.

    Subclasses define ``__init__`` with keyword hyperparameters only, declare their
    constraints in ``_parameter_constraints`` (parameter -> Interval/Options/...), and implement
    ``_fit`` and ``_predict_proba``. Their id is the name they are registered under.
    """

    name: ClassVar[str] = ""  # set by the registry on each class it loads: the plugin's id

    # -- input checks
    @staticmethod
    def _check_x(x: Any) -> np.ndarray:
        x = np.asarray(x, dtype=np.float32)
        if x.ndim != 2:
            raise UsageError(f"windows must be a 2-D array (n_windows, window_length), got shape {x.shape}")
        if x.shape[0] == 0:
            raise UsageError("no windows given")
        if x.shape[1] < MIN_WINDOW:
            raise UsageError(f"windows must have at least {MIN_WINDOW} samples, got {x.shape[1]}")
        bad = ~np.isfinite(x)
        if bad.any():
            row, col = np.argwhere(bad)[0]
            raise UsageError(f"windows contain NaN or infinity (first at window {row}, sample {col})")
        return np.ascontiguousarray(x)

    def _check_fitted(self) -> None:
        if not getattr(self, "window_length_", None):
            raise NotFittedError(f"this {type(self).__name__} is not fitted yet; call fit before predict")

    # -- the public API
    def fit(self, x: Any, y: Any, *, sampling_rate: float = 1000.0, seed: int = 0) -> "BaseDetector":
        """Fit on windows ``x`` (n_windows, window_length) and labels ``y`` (1 = slip).

        ``sampling_rate`` (Hz) lets spectral detectors speak in hertz; ``seed`` drives every
        random choice the detector makes.
        """
        self.validate_params()
        x = self._check_x(x)
        y = np.asarray(y)
        if y.shape != (x.shape[0],):
            raise UsageError(f"labels must have shape ({x.shape[0]},), got {y.shape}")
        if not np.isin(y, (0, 1)).all():
            raise UsageError("labels must be 0 (no slip) or 1 (slip)")
        if len(np.unique(y)) < 2:
            raise UsageError(f"training data holds only class {int(y[0])}; a detector needs slip and non-slip windows")
        if not (np.isfinite(sampling_rate) and sampling_rate > 0):
            raise UsageError(f"sampling_rate must be a positive number of Hz, got {sampling_rate}")
        self.sampling_rate_ = float(sampling_rate)
        self.window_length_ = x.shape[1]
        self._fit(x, y.astype(np.int8), seed)
        return self

    def predict_proba(self, x: Any) -> np.ndarray:
        """Probability of slip per window, shape (n_windows,)."""
        self._check_fitted()
        x = self._check_x(x)
        if x.shape[1] != self.window_length_:
            raise UsageError(f"fitted on windows of {self.window_length_} samples, got {x.shape[1]}")
        return self._checked_output(self._predict_proba(x), len(x))

    def _checked_output(self, scores: Any, n: int) -> np.ndarray:
        """The plugin's scores as (n,) float64, or DetectorOutputError saying what is wrong:
        a wrong number would otherwise pass as a result (NaN scores read as 50 % accuracy)."""
        who = f"detector {plugin_id(type(self))!r}"
        try:
            scores = np.asarray(scores, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise DetectorOutputError(f"{who} returned scores that are not numbers: {exc}") from None
        if scores.shape != (n,):
            raise DetectorOutputError(f"{who} returned scores of shape {scores.shape} for {n} windows; expected ({n},)")
        bad = ~np.isfinite(scores)
        if bad.any():
            raise DetectorOutputError(f"{who} returned {int(bad.sum())} non-finite scores (NaN or infinity) of {n}, "
                                      f"first at window {int(np.argmax(bad))}")
        outside = (scores < 0) | (scores > 1)
        if outside.any():
            raise DetectorOutputError(f"{who} returned {int(outside.sum())} scores outside [0, 1] of {n} "
                                      f"(from {scores.min():g} to {scores.max():g}); predict_proba gives probabilities")
        return scores

    def predict(self, x: Any) -> np.ndarray:
        """1 where the detector calls slip, shape (n_windows,)."""
        return (self.predict_proba(x) >= 0.5).astype(np.int8)

    # -- streaming: a robot's control loop
    def streamer(self, hop: int, threshold: float = 0.5) -> Streamer:
        """A causal stream through this fitted detector (see :mod:`slipbench.streamer`).

        ``stream = detector.streamer(hop)``; ``scores, decisions = stream.push(samples)`` takes any
        number of new samples of the univariate signal and gives one score and one 0/1 decision
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

    # -- persistence without pickle: parameters as JSON, fitted attributes as plain arrays
    def save(self, path: str | os.PathLike) -> None:
        """Write the fitted detector to ``path`` (an .npz that ``np.load(allow_pickle=False)``
        reads). Fitted attributes must be arrays, numbers, strings or tuples/lists of them."""
        self._check_fitted()
        arrays, kinds = {}, {}
        for key, value in vars(self).items():
            if key.endswith("_") and not key.startswith("_"):
                arrays[key] = np.asarray(value)
                if arrays[key].dtype == object:
                    raise UsageError(f"cannot save {type(self).__name__}: fitted attribute {key!r} holds a "
                                     f"{type(value).__name__}, not an array, number or string")
                kinds[key] = type(value).__name__ if isinstance(value, (tuple, list, np.ndarray)) else "scalar"
        cls = type(self)
        meta = {"format": "slipbench-detector-1", "class": f"{cls.__module__}:{cls.__qualname__}",
                "name": plugin_id(cls), "params": _encode(self.get_params()), "kinds": kinds}
        # a unique temporary name: two processes may save the same model key at once
        with atomic_file(path) as f:
            np.savez(f, __meta__=np.array(json.dumps(meta)), **arrays)

    @classmethod
    def load(cls, path: str | os.PathLike) -> "BaseDetector":
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
            raise UsageError(f"{path} holds a {meta['class']} ({meta['name']!r}), not a {cls.__name__}")
        detector = cls(**_decode(meta["params"]))
        for key, value in arrays.items():
            kind = meta["kinds"][key]
            detector.__dict__[key] = value.item() if kind == "scalar" else value if kind == "ndarray" else \
                (tuple if kind == "tuple" else list)(value.tolist())
        return detector

    def fitted_choices(self) -> dict[str, Any]:
        """What fitting chose that a reader of the results should see (plain JSON values): a
        band in Hz as ``band_hz`` [low, high], a ``threshold``, .... Stored in each result row
        and shown by the report; a band at 0 Hz or reaching Nyquist is flagged there."""
        return {}

    @classmethod
    def benchmark(cls, length: int, seconds: float, seed: int = 0) -> Any:
        """Optional: the detector's own speed figures (a DataFrame) against a reference timed in
        the same run, shown by ``slipbench bench``; None when it has none."""
        return None

    # -- what plugins implement
    def _fit(self, x: np.ndarray, y: np.ndarray, seed: int) -> None:
        raise NotImplementedError

    def _predict_proba(self, x: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class DetectorOutputError(PluginError):
    """A detector returned scores that are not one probability per window."""


def _saved_class(target: str, path: Any) -> type:
    """The class ``module:qualname`` of a saved detector, from an imported module or an
    installed plugin's module."""
    module_name, _, qualname = target.partition(":")
    module = sys.modules.get(module_name)
    if module is None and (module_name.startswith("slipbench.") or any(
            ep.value.partition(":")[0] == module_name for ep in entry_points(group=DETECTOR_GROUP))):
        module = importlib.import_module(module_name)
    obj = module
    for part in qualname.split(".") if module is not None else ():
        obj = getattr(obj, part, None)
    if not (isinstance(obj, type) and issubclass(obj, BaseDetector)):
        raise UsageError(f"{path} holds a {target}, which is not an installed detector; load its plugin first "
                         "(a plugin folder: slipbench.registry.add_plugin_folder) or call TheClass.load")
    return obj


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
        return tuple(_decode(v) for v in value["__tuple__"]) if "__tuple__" in value else {k: _decode(v) for k, v in value.items()}
    return [_decode(v) for v in value] if isinstance(value, list) else value


def clone(detector: BaseDetector) -> BaseDetector:
    """A new, unfitted detector with the same hyperparameters."""
    return type(detector)(**copy.deepcopy(detector.get_params()))
