"""The order values take in every table, figure and finding: the paper's where it has one
(:data:`slipbench.vocabulary.ORDERS`), else numbers ascending, then the rest alphabetically."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

from slipbench.vocabulary import ORDERS


def rank(values: Iterable[Any], order: Sequence[Any] = ()) -> list[Any]:
    """Known values in ``order`` first, then numbers ascending, then the rest alphabetically."""

    def key(v):
        if v in order:
            return (0, order.index(v), "")
        try:
            return (1, float(v), "")
        except (TypeError, ValueError):
            return (2, 0.0, str(v))

    return sorted(set(values), key=key)


def ordered(values: Iterable[Any], column: str) -> list[Any]:
    """A column's values in the paper's order for it (:func:`rank`)."""
    out = rank(values, ORDERS.get(column, ()))
    return out[::-1] if column == "downsample" else out  # the paper puts the lowest rate first
