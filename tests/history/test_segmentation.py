"""The numpy binary segmentation gives ruptures' breakpoints exactly: ruptures is the oracle."""

from __future__ import annotations

import numpy as np
import pytest
import ruptures as rpt
from ruptures.base import BaseCost

from slipbench.history.segmentation import weighted_binseg
from slipbench.history.steps import MIN_RUNS


class WeightedL2(BaseCost):
    """The cost the step search used with ruptures' Binseg (the oracle): sum of
    ``w * (y - mean_w)**2``, ``w`` each point's precision, in O(1) from prefix sums. The
    signal is (n, 2): the values and their weights."""

    model = "weighted-l2"
    min_size = MIN_RUNS

    def fit(self, signal: np.ndarray) -> WeightedL2:
        y, w = signal[:, 0], signal[:, 1]
        # lists: one element read is 3x faster than from an array, and Binseg reads 4n of them
        self._w = np.concatenate([[0.0], np.cumsum(w)]).tolist()
        self._s = np.concatenate([[0.0], np.cumsum(w * y)]).tolist()
        self._q = np.concatenate([[0.0], np.cumsum(w * y * y)]).tolist()
        self.signal = signal
        return self

    def error(self, start: int, end: int) -> float:
        s = self._s[end] - self._s[start]
        return self._q[end] - self._q[start] - s * s / (self._w[end] - self._w[start])


def _ruptures(value: np.ndarray, weight: np.ndarray, pen: float, min_size: int) -> list[int]:
    cost = WeightedL2()
    cost.min_size = min_size  # the instance's: Binseg takes the larger of it and its own
    algo = rpt.Binseg(custom_cost=cost, min_size=min_size, jump=1)
    return [int(b) for b in algo.fit(np.column_stack([value, weight])).predict(pen=pen)[:-1]]


def _series(rng: np.random.Generator, n: int, kind: int) -> tuple[np.ndarray, np.ndarray]:
    """Steps in noise with uneven weights; integers (exact sums: gains tie); flat; mirrored."""
    if kind == 0:
        level = np.repeat(rng.normal(0, 1, 4), -(-n // 4))[:n]
        return level + rng.normal(0, 0.3, n), rng.uniform(0.2, 5.0, n)
    if kind == 1:
        return rng.integers(0, 3, n).astype(float), rng.integers(1, 3, n).astype(float)
    if kind == 2:
        return np.full(n, 0.8), np.ones(n)
    half = rng.integers(0, 2, -(-n // 2)).astype(float)
    return np.concatenate([half, half[::-1]])[:n], np.ones(n)


@pytest.mark.parametrize("min_size", [1, 2, MIN_RUNS])
def test_the_breakpoints_are_ruptures_on_random_series(min_size):
    rng = np.random.default_rng(min_size)
    compared = ties = 0
    for i in range(400):
        n = int(rng.integers(min_size, 60)) if i % 2 else int(rng.integers(2 * min_size, 400))
        value, weight = _series(rng, n, i % 4)
        pen = float(rng.choice([1e-9, 0.5, 2.0, 10.0, 6.0 * np.log(n)]))
        mine = weighted_binseg(value, weight, pen, min_size)
        assert mine == _ruptures(value, weight, pen, min_size), (i, n, pen)
        compared += 1
        ties += i % 4 in (1, 3) and bool(mine)
    assert compared == 400 and ties > 20  # integer series cut often: their tied gains count


def test_a_series_too_short_to_cut_has_no_breakpoint():
    for n in range(MIN_RUNS, 2 * MIN_RUNS):
        value = np.arange(n, dtype=float)
        assert weighted_binseg(value, np.ones(n), 1e-9, MIN_RUNS) == []
        assert _ruptures(value, np.ones(n), 1e-9, MIN_RUNS) == []
    assert weighted_binseg(np.array([1.0]), np.ones(1), 1e-9, MIN_RUNS) == []


@pytest.mark.parametrize(
    "value, weight, min_size",
    [
        ([1.0, np.nan, 2.0], [1.0, 1.0, 1.0], 1),
        ([1.0, 2.0, 3.0], [1.0, 0.0, 1.0], 1),
        ([1.0, 2.0, 3.0], [1.0, np.inf, 1.0], 1),
        ([1.0, 2.0, 3.0], [1.0, 1.0], 1),
        ([1.0, 2.0, 3.0], [1.0, 1.0, 1.0], 0),
    ],
)
def test_a_bad_series_is_refused(value, weight, min_size):
    with pytest.raises(ValueError):
        weighted_binseg(np.array(value), np.array(weight), 1.0, min_size)
