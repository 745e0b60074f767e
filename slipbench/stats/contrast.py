"""The interval of a contrast of cells (a weighted sum of their figures: a rise, a drop, a lead)
from the intervals the cells' rows hold, for judging the paper's findings.

Each cell's standard error is read from its interval, (hi - lo) / (2 z) (normal approximation).
Cells of one *unit* (the cells that test the same test windows: one sensor at several windows
or rates, two detectors on one unit) are combined as independent: their errors move together,
and for a contrast whose weights sum to zero that positive correlation only narrows the true
spread, so the independent sum is conservative. Units are then added by their standard
errors (the Minkowski bound, valid whatever the correlation: fingers share trials). The
interval is therefore wide rather than narrow: a finding it supports is supported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.stats import norm

LEVEL = 0.95


@dataclass(frozen=True)
class Estimate:
    """A contrast (in the cells' unit) and its interval; NaN bounds where a cell has none."""

    value: float
    lo: float
    hi: float

    @property
    def judged(self) -> bool:
        return bool(np.isfinite(self.value) and np.isfinite(self.lo) and np.isfinite(self.hi))

    def scaled(self, factor: float) -> Estimate:
        return Estimate(self.value * factor, self.lo * factor, self.hi * factor)


def contrast(terms: pd.DataFrame, level: float = LEVEL) -> Estimate:
    """``terms``: one line per cell with ``unit``, ``weight``, ``mean``, ``lo``, ``hi``.
    Returns the weighted sum of the means with the interval described in the module."""
    if terms.empty:
        return Estimate(np.nan, np.nan, np.nan)
    z = float(norm.ppf(0.5 + level / 2))
    w = terms["weight"].to_numpy(dtype=float)
    value = float(np.sum(w * terms["mean"].to_numpy(dtype=float)))
    se = (terms["hi"].to_numpy(dtype=float) - terms["lo"].to_numpy(dtype=float)) / (2 * z)
    if not np.all(np.isfinite(se)):
        return Estimate(value, np.nan, np.nan)
    var = pd.Series((w * se) ** 2, index=terms.index).groupby(terms["unit"].to_numpy()).sum()
    half = z * float(np.sqrt(var).sum())
    return Estimate(value, value - half, value + half)
