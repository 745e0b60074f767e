"""The interval of a contrast of cells (a weighted sum of their figures: a rise, a drop, a lead)
from the intervals the cells' rows hold, for judging the paper's findings.

Each cell's standard error is read from its interval, (hi - lo) / (2 z) (normal approximation).
Cells of one *unit* (the cells that test the same test windows: one sensor at several windows
or rates, two detectors on one unit) are combined as independent: their errors move together,
and for a contrast whose weights sum to zero that positive correlation only narrows the true
spread, so the independent sum is conservative. Units are then added by their standard
errors (the Minkowski bound, valid whatever the correlation: fingers share trials).

Measured (``benchmarks/bench_findings_contrast.py``: three fingers recorded in the same trials,
10 and 20 trials per class, 500 replications per setting, against closed-form truths; table in
``docs/coverage.md``), for the window rise, the change beyond window 50, the TP - TN gap and the
lead over a baseline:

- test noise only: coverage 0.982-1.000, the intervals 1.3-6.7 times as wide as the estimates'
  spread needs: conservative, as built;
- retraining noise (a seed shifts a cell's accuracy by about 6 points, SD) with one seed per
  cell: 0.956-0.992; at about 12 points: 0.72-0.89 (the gap 0.98): the rows' intervals hold
  test noise only, and no interval built from one seed's rows can see retraining noise;
- three seeds per cell (the contrast taken per seed, :func:`contrast`): 0.982-1.000 at both
  noise levels, 2.0-3.6 times as wide as needed (the gap 1.3-1.6).

So the contrast is conservative where its rows hold every noise there is, and undercovers only
by what one seed leaves out, which nothing in one seed's rows measures: the findings table says
so where its rows hold one seed per cell (``ONE_SEED_COVERAGE``), and repeats correct it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
import scipy  # scipy.stats loads on first use (see slipbench.stats)

from slipbench.stats.metrics import seeds_from_rows

LEVEL = 0.95
#: measured coverage of the contrasts with one seed per cell where retraining moves a cell's
#: accuracy by about 12 points (module docstring)
ONE_SEED_COVERAGE = "0.72-0.89"


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
    Returns the weighted sum of the means with the interval described in the module.

    With a ``seed`` column of several seeds (each seed's lines, the same cells for every seed,
    each line one seed's row): the contrast is taken per seed, and their mean gets
    :func:`slipbench.stats.metrics.seeds_from_rows`' interval, each seed's standard error its
    contrast's half-width over z: the spread of the seeds' contrasts measures the retraining
    noise of the contrast itself. Summing each cell's own spread over seeds instead counts it
    through the units' bound too: the window rise at three seeds was 49-54 points wide that way,
    35-44 per seed, both covering 1.000 (module docstring's study, 500 replications)."""
    if terms.empty:
        return Estimate(np.nan, np.nan, np.nan)
    if "seed" in terms and terms["seed"].nunique() > 1:
        z = float(scipy.stats.norm.ppf(0.5 + level / 2))
        per = [_one_seed(t, level) for _, t in terms.groupby("seed", sort=True)]
        ses = [(e.hi - e.lo) / (2 * z) for e in per]
        return Estimate(*seeds_from_rows(np.array([e.value for e in per]), np.array(ses), level))
    return _one_seed(terms, level)


def _one_seed(terms: pd.DataFrame, level: float) -> Estimate:
    """The contrast of one seed's (or one summary's) lines, with the module's interval."""
    z = float(scipy.stats.norm.ppf(0.5 + level / 2))
    w = terms["weight"].to_numpy(dtype=float)
    value = float(np.sum(w * terms["mean"].to_numpy(dtype=float)))
    se = (terms["hi"].to_numpy(dtype=float) - terms["lo"].to_numpy(dtype=float)) / (2 * z)
    if not np.all(np.isfinite(se)):
        return Estimate(value, np.nan, np.nan)
    var = pd.Series((w * se) ** 2, index=terms.index).groupby(terms["unit"].to_numpy()).sum()
    half = z * float(np.sqrt(var).sum())
    return Estimate(value, value - half, value + half)
