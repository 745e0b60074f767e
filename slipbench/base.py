"""The contracts plugins implement: BaseDetector and BaseProtocol.

Detectors follow scikit-learn's estimator conventions: ``__init__`` stores keyword
hyperparameters under their own names and nothing else; fitted state ends in ``_``;
``get_params``/``set_params``/``clone`` come from the base class. The base class owns ``fit``,
``predict_proba`` and ``predict``: it validates parameters and input once, then calls the
plugin's ``_fit`` and ``_predict_proba``, which never re-check.
"""

from __future__ import annotations

import copy
import inspect
import json
import os
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from .atomic import atomic_file
from .errors import UsageError

MIN_WINDOW = 5


class NotFittedError(UsageError):
    """predict was called before fit."""


# ----------------------------------------------------------------------------- parameters
@dataclass(frozen=True)
class Interval:
    """A number of ``kind`` in [low, high] (either bound may be None)."""

    kind: type
    low: float | None
    high: float | None

    def check(self, value: Any) -> bool:
        if isinstance(value, bool) or not isinstance(value, self.kind if self.kind is not float else (int, float)):
            return False
        return (self.low is None or value >= self.low) and (self.high is None or value <= self.high)

    def __str__(self) -> str:
        name = "an int" if self.kind is int else "a float"
        lo = "-inf" if self.low is None else self.low
        hi = "inf" if self.high is None else self.high
        return f"{name} in [{lo}, {hi}]"


@dataclass(frozen=True)
class Options:
    """One of the listed values."""

    values: tuple

    def check(self, value: Any) -> bool:
        return value in self.values

    def __str__(self) -> str:
        return "one of " + ", ".join(repr(v) for v in self.values)


@dataclass(frozen=True)
class Band:
    """A (low_hz, high_hz) pair with 0 <= low < high, or None for a band chosen from data."""

    def check(self, value: Any) -> bool:
        if value is None:
            return True
        try:
            lo, hi = (float(v) for v in value)
        except (TypeError, ValueError):
            return False
        return 0 <= lo < hi

    def __str__(self) -> str:
        return "None or a (low_hz, high_hz) pair with 0 <= low < high"


# ----------------------------------------------------------------------------- detectors
class BaseDetector:
    """A binary slip detector on windows of a univariate signal.

    Subclasses set ``name`` and ``_parameter_constraints`` (parameter -> Interval/Options/...),
    define ``__init__`` with keyword hyperparameters only, and implement ``_fit`` and
    ``_predict_proba``.
    """

    name: ClassVar[str] = ""
    _parameter_constraints: ClassVar[dict[str, Any]] = {}

    # -- scikit-learn parameter protocol
    @classmethod
    def _param_names(cls) -> list[str]:
        sig = inspect.signature(cls.__init__)
        return sorted(p.name for p in sig.parameters.values() if p.name != "self" and p.kind != p.VAR_KEYWORD)

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self._param_names()}

    def set_params(self, **params: Any) -> "BaseDetector":
        valid = self._param_names()
        for k, v in params.items():
            if k not in valid:
                raise UsageError(f"{type(self).__name__} has no parameter {k!r}; its parameters: {', '.join(valid) or 'none'}")
            setattr(self, k, v)
        return self

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({args})"

    def validate_params(self) -> None:
        """Raise UsageError naming the first hyperparameter outside its constraint."""
        for key, constraint in self._parameter_constraints.items():
            value = getattr(self, key)
            if not constraint.check(value):
                raise UsageError(
                    f"The {key!r} parameter of {type(self).__name__} must be {constraint}. Got {value!r} instead."
                )

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
        return np.asarray(self._predict_proba(x), dtype=np.float64)

    def predict(self, x: Any) -> np.ndarray:
        """1 where the detector calls slip, shape (n_windows,)."""
        return (self.predict_proba(x) >= 0.5).astype(np.int8)

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
        meta = {"format": "slipbench-detector-1", "class": type(self).__name__, "name": self.name,
                "params": _encode(self.get_params()), "kinds": kinds}
        # a unique temporary name: two processes may save the same model key at once
        with atomic_file(path) as f:
            np.savez(f, __meta__=np.array(json.dumps(meta)), **arrays)

    @classmethod
    def load(cls, path: str | os.PathLike) -> "BaseDetector":
        """Read a detector written by :meth:`save`. ``BaseDetector.load`` finds its class in the
        registry by name; ``SomeDetector.load`` insists on that class."""
        try:
            with np.load(path, allow_pickle=False) as f:
                meta = json.loads(str(f["__meta__"]))
                arrays = {k: f[k] for k in f.files if k != "__meta__"}
        except (OSError, ValueError, KeyError) as exc:
            raise UsageError(f"{path} is not a saved slipbench detector: {exc}") from exc
        if cls is BaseDetector:
            from .registry import detectors

            cls = detectors.get(meta["name"])
        elif meta["class"] != cls.__name__:
            raise UsageError(f"{path} holds a {meta['class']} ({meta['name']!r}), not a {cls.__name__}")
        detector = cls(**_decode(meta["params"]))
        for key, value in arrays.items():
            kind = meta["kinds"][key]
            detector.__dict__[key] = value.item() if kind == "scalar" else value if kind == "ndarray" else \
                (tuple if kind == "tuple" else list)(value.tolist())
        return detector

    # -- what plugins implement
    def _fit(self, x: np.ndarray, y: np.ndarray, seed: int) -> None:
        raise NotImplementedError

    def _predict_proba(self, x: np.ndarray) -> np.ndarray:
        raise NotImplementedError


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


# ----------------------------------------------------------------------------- protocols
@dataclass(frozen=True)
class Part:
    """Windows that train or test a cell.

    ``sensors``: the (sensor_type, instance) pairs whose windows are pooled; ``side``: which half
    of each sensor's balanced split ("train" or "test"); ``where``: filters on recording columns,
    as (column, "==" or "!=", value) triples, applied to the windows of that half.
    """

    sensors: tuple[tuple[str, str], ...]
    side: str
    where: tuple[tuple[str, str, Any], ...] = ()


@dataclass(frozen=True)
class Cell:
    """One entry of a protocol's table: what trains, what tests, at which window and rate.

    ``key`` names the cell in results and tables (e.g. sensor, instance, window).
    """

    key: dict[str, Any]
    train: Part
    test: Part
    window: int
    downsample: int = 1
    decimation: str = "plain"  # "plain": every k-th sample (the paper); "antialias": low-pass first
    skip: str = ""  # a reason the cell cannot run on this dataset, reported instead of results


class BaseProtocol:
    """A standardized experiment: a list of cells built from the dataset's metadata alone.

    Protocols never train anything; the runner does. ``table`` names the result columns that
    make the rows and columns of the protocol's table. Options are keyword arguments of
    ``__init__``, like detector hyperparameters.
    """

    name: ClassVar[str] = ""
    table: ClassVar[dict[str, Any]] = {}

    def cells(self, recordings) -> Iterable[Cell]:
        raise NotImplementedError

    def columns(self, recordings) -> dict[str, Any]:
        """Extra per-recording columns that this protocol's ``where`` filters refer to."""
        return {}

    def get_params(self) -> dict[str, Any]:
        names = [p for p in inspect.signature(type(self).__init__).parameters if p != "self"]
        return {k: getattr(self, k) for k in names if hasattr(self, k)}
