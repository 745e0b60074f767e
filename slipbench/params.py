"""Declared, validated keyword parameters: what detectors and protocols share.

A plugin class lists its parameters as keyword arguments of ``__init__``, stored under their
own names (scikit-learn's convention), and declares their constraints in
``_parameter_constraints``, a dict from parameter name to one of the constraint types below.
:class:`Parameterized` gives ``get_params``, ``set_params``, ``validate_params`` and ``repr``.
"""

from __future__ import annotations

import inspect
import math
from dataclasses import dataclass
from typing import Any, ClassVar, TypeVar

from slipbench.errors import UsageError
from slipbench.vocabulary import MAX_WINDOW, MAX_WINDOW_MS, MIN_WINDOW


@dataclass(frozen=True)
class Interval:
    """A number of ``kind`` (int or float; an int is a valid float) in [low, high]; either bound
    may be None."""

    kind: type[float]  # int or float (mypy counts an int as a float)
    low: float | None
    high: float | None

    def check(self, value: Any) -> bool:
        kinds = (int, float) if self.kind is float else (self.kind,)
        if (
            isinstance(value, bool)
            or not isinstance(value, kinds)
            or (isinstance(value, float) and math.isnan(value))
        ):
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
        try:
            return value in self.values
        except TypeError:  # an unhashable or incomparable value is not an option
            return False

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


@dataclass(frozen=True)
class Sequence:
    """One value meeting ``item``, or a non-empty list/tuple of such values."""

    item: Any

    def check(self, value: Any) -> bool:
        if isinstance(value, (list, tuple)):
            return len(value) > 0 and all(self.item.check(v) for v in value)
        return self.item.check(value)

    def __str__(self) -> str:
        return f"{self.item}, or a non-empty list of them"


@dataclass(frozen=True)
class WindowLength:
    """A window length: an int number of samples (>= ``low``), or milliseconds as a string
    "50ms", converted per sensor by its sampling rate (:func:`window_samples`)."""

    low: int = MIN_WINDOW

    def check(self, value: Any) -> bool:
        if isinstance(value, str):
            return (parse_ms(value) or math.inf) <= MAX_WINDOW_MS
        return Interval(int, self.low, MAX_WINDOW).check(value)

    def __str__(self) -> str:
        return (
            f"an int number of samples in [{self.low}, {MAX_WINDOW}], or milliseconds such as "
            f"'50ms' (at most {MAX_WINDOW_MS:.0f}, an hour)"
        )


def parse_ms(text: str) -> float | None:
    """50.0 for "50ms" or "50 ms"; None when ``text`` is not a positive duration in ms."""
    text = text.strip().lower()
    if not text.endswith("ms"):
        return None
    try:
        value = float(text[:-2])
    except ValueError:
        return None
    return value if math.isfinite(value) and value > 0 else None


def window_samples(window: int | str, rate_hz: float) -> int:
    """Samples of a window given in samples (int) or milliseconds ("50ms") at ``rate_hz``."""
    if isinstance(window, str):
        ms = parse_ms(window)
        if ms is None:  # a validated window length never is
            raise UsageError(f"not a window length in samples or milliseconds: {window!r}")
        return int(round(ms * rate_hz / 1000.0))
    return int(window)


def param_names(cls: type[object]) -> list[str]:
    """The keyword parameters of ``cls.__init__`` (none when the class defines no ``__init__``)."""
    if cls.__init__ is object.__init__:
        return []
    sig = inspect.signature(cls.__init__)
    kinds = (inspect.Parameter.VAR_KEYWORD, inspect.Parameter.VAR_POSITIONAL)
    return sorted(
        p.name for p in sig.parameters.values() if p.name != "self" and p.kind not in kinds
    )


def param_defaults(cls: type[object]) -> dict[str, Any]:
    """Each parameter's default value (``inspect.Parameter.empty`` where there is none)."""
    if cls.__init__ is object.__init__:
        return {}
    sig = inspect.signature(cls.__init__)
    return {name: sig.parameters[name].default for name in param_names(cls)}


_Self = TypeVar("_Self", bound="Parameterized")


class Parameterized:
    """scikit-learn's parameter protocol for plugins: get/set, validate, repr."""

    _parameter_constraints: ClassVar[dict[str, Any]] = {}

    @classmethod
    def _param_names(cls) -> list[str]:
        return param_names(cls)

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """The parameters (keyword arguments of ``__init__``) by name, as stored; ``deep`` is
        scikit-learn's and changes nothing here (no parameter is itself an estimator)."""
        return {k: getattr(self, k) for k in self._param_names()}

    def set_params(self: _Self, **params: Any) -> _Self:
        """Set parameters by name and return ``self``; an unknown name is a UsageError listing
        the known ones. Values are checked by :meth:`validate_params` (``fit`` calls it)."""
        valid = self._param_names()
        for k, v in params.items():
            if k not in valid:
                raise UsageError(
                    f"{type(self).__name__} has no parameter {k!r}; its parameters: {', '.join(valid) or 'none'}"
                )
            setattr(self, k, v)
        return self

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({args})"

    def validate_params(self) -> None:
        """Raise UsageError naming the first parameter outside its constraint."""
        for key, constraint in self._parameter_constraints.items():
            value = getattr(self, key)
            if not constraint.check(value):
                raise UsageError(
                    f"The {key!r} parameter of {type(self).__name__} must be {constraint}. Got {value!r} instead."
                )
