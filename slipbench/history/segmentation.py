"""Binary segmentation of a weighted series in numpy: ruptures' ``Binseg`` without its loops.

A history's steps are proposed by binary segmentation under a cost that weighs every point by
its precision (the sum of ``w * (y - mean_w)**2`` of each segment). ``ruptures.Binseg`` reads
that cost once per candidate breakpoint from Python, so a series of 10,000 runs costs tens of
thousands of Python calls per level; here each segment's every candidate is one array
expression over prefix sums. The arithmetic and the order of its operations are ruptures' own
under that cost (``jump=1``), and so are its choices among ties: within a segment the latest of
the equal best breakpoints, among segments the first (in position) of the equal best gains.
So the breakpoints are ruptures' exactly (``tests/history/test_segmentation.py`` holds it to
ruptures on random series, ties and short series included).
"""

from __future__ import annotations

import numpy as np


def _prefix(values: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(values)])


def weighted_binseg(value: np.ndarray, weight: np.ndarray, pen: float, min_size: int) -> list[int]:
    """The breakpoints of binary segmentation under the weighted squared error, penalized.

    Parameters
    ----------
    value : the series (finite).
    weight : each point's weight (finite, > 0): its precision, 1 / its standard error squared.
    pen : the gain a cut must exceed to be made.
    min_size : the fewest points a segment holds (>= 1).

    Returns
    -------
    list of int
        The indices where a new segment starts, ascending (empty: no cut); what
        ``ruptures.Binseg(custom_cost=<this cost>, min_size=min_size, jump=1)`` predicts with
        ``pen``, its last element (the series' length) left out.

    Raises
    ------
    ValueError
        A value or weight is not finite, a weight is not positive, the lengths differ or
        ``min_size`` is below 1.
    """
    y = np.asarray(value, dtype=float)
    w = np.asarray(weight, dtype=float)
    if y.shape != w.shape or y.ndim != 1:
        raise ValueError(f"values {y.shape} and weights {w.shape} are not one series")
    if min_size < 1:
        raise ValueError(f"a segment holds at least 1 point, got min_size {min_size}")
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(w)) and np.all(w > 0)):
        raise ValueError("binary segmentation needs finite values and finite positive weights")
    n = len(y)
    if n < 2 * min_size:
        return []
    # the cost's prefix sums as WeightedL2.fit makes them: the same cumulative sums
    sw, sy, sq = _prefix(w), _prefix(w * y), _prefix(w * y * y)

    def error(start: np.ndarray | int, end: np.ndarray | int) -> np.ndarray:
        s = sy[end] - sy[start]
        return sq[end] - sq[start] - s * s / (sw[end] - sw[start])

    best: dict[tuple[int, int], tuple[int | None, float]] = {}

    def single(start: int, end: int) -> tuple[int | None, float]:
        """The best cut of [start, end) and its gain (None, 0 where none fits)."""
        if (start, end) not in best:
            cuts = np.arange(start + min_size, end - min_size + 1)
            if len(cuts) == 0:
                best[start, end] = (None, 0.0)
            else:
                gain = error(start, end) - error(start, cuts) - error(cuts, end)
                top = gain.max()
                at = len(gain) - 1 - int(np.argmax(gain[::-1] == top))  # the latest of ties
                best[start, end] = (int(cuts[at]), float(top))
        return best[start, end]

    bkps = [n]
    while True:
        found = [single(a, b) for a, b in zip([0, *bkps], bkps)]
        cut, gain = max(found, key=lambda x: x[1])  # the first of equal gains
        if cut is None or not gain > pen:
            break
        bkps = sorted([*bkps, cut])
    return bkps[:-1]
