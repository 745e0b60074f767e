"""Steps in short series: fewer runs than the segment search needs, judged on the runs' own
intervals.

Binary segmentation (:mod:`slipbench.history.steps`) needs ``MIN_RUNS`` runs on each side of a
step, so a series of fewer than ``2 * MIN_RUNS`` points never shows one. A short series (at
least :data:`FEWEST` points) is searched here instead: every cut between two runs is a
candidate, and the one whose change is largest against its noise is the proposal, judged by
the gate's contrast (:func:`slipbench.stats.contrast.from_parts`) against the tolerance at
``1 - SERIES_ALPHA / (points - 1)``: Bonferroni over the cuts looked at.

The noise of a side's mean comes from what each run recorded of its own sampling: its
interval's standard error and degrees of freedom (a run of several seeds holds their spread),
one component per run. Runs of different commits also differ by their seeds' splits and
training, which no single run's interval holds, so two corrections enter:

- the history's *scale*: per figure and kind of series, how much more the short series move
  from run to run than their intervals say (the robust spread of every series' successive
  differences in units of their standard errors, squared, at least 1), multiplies each run's
  variance;
- the *scatter*: where a side holds two runs or more, the runs' spread about their side's mean
  (pooled over both sides, ``points - 2`` degrees of freedom) is a second measure of a run's
  noise; the contrast takes whichever of the two is larger.

``benchmarks/bench_short_steps.py`` measures the false alarms and the power of this route on
short histories drawn from a pool of real runs (``benchmarks/results/short_steps.md``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from slipbench.stats.contrast import Contrast, from_parts

#: the fewest points a series needs for a step to be searched in it
FEWEST = 3
#: how steps of each route are said to be judged (``route`` of a step)
SHORT = "short"
LONG = "long"
#: the noise a short step's interval holds (its ``noise``)
OWN = "each run's own interval, times the history's run-to-run scale"
SCATTER = "the runs' scatter about their sides' means"
ROUTES = {
    SHORT: "judged on the runs' own intervals (a short series)",
    LONG: "judged on the segments' seeds",
}


def scale(series: list[tuple[np.ndarray, np.ndarray]]) -> float:
    """How much more the ``series`` (each its values and standard errors, oldest first) move
    from run to run than their intervals say: the squared robust (MAD) spread of all their
    successive differences over those differences' standard errors; at least 1, 1 where fewer
    than 3 differences are measured."""
    z = [
        np.diff(v) / np.sqrt(s[1:] ** 2 + s[:-1] ** 2)
        for v, s in series
        if len(v) > 1 and np.all(np.isfinite(s)) and np.all(s > 0)
    ]
    flat = np.concatenate(z) if z else np.array([])
    flat = flat[np.isfinite(flat)]
    if len(flat) < 3:
        return 1.0
    mad = 1.4826 * float(np.median(np.abs(flat - np.median(flat))))
    return max(1.0, mad**2)


def _parts(
    value: np.ndarray, se: np.ndarray, df: np.ndarray, k: int, factor: float
) -> list[tuple[float, float]]:
    """The variance of the change at cut ``k`` as components: each run's own (its standard
    error squared, scaled, over its side's runs squared, on its degrees of freedom), or the
    runs' scatter about their sides' means where that is larger."""
    n = len(value)
    sides = (slice(0, k), slice(k, n))
    counts = (k, n - k)
    own = [
        (factor * float(s) ** 2 / m**2, float(d))
        for part, m in zip(sides, counts)
        for s, d in zip(se[part], df[part])
    ]
    if n > 2:
        resid = np.concatenate([value[p] - value[p].mean() for p in sides])
        spread = float(np.sum(resid**2)) / (n - 2)
        scatter = spread * (1 / counts[0] + 1 / counts[1])
        if scatter > sum(v for v, _ in own):
            return [(scatter, float(n - 2))]
    return own


def _noise(parts: list[tuple[float, float]], n: int) -> str:
    return SCATTER if len(parts) == 1 and n > 1 else OWN


def short_change(
    points: tuple[np.ndarray, np.ndarray, np.ndarray],
    factor: float,
    level: float,
    margin: float,
) -> tuple[int, Contrast]:
    """The proposal of a short series (``points``: values, standard errors, degrees of
    freedom, oldest first) and its change as a contrast at ``level`` against ``margin``: the
    cut (the index of the first run after it) whose change is largest against its noise.

    Raises
    ------
    ValueError
        Fewer than :data:`FEWEST` points, or the arrays differ in length.
    """
    value, se, df = (np.asarray(x, float) for x in points)
    n = len(value)
    if n < FEWEST or len(se) != n or len(df) != n:
        raise ValueError(f"a short series holds {FEWEST} points or more of value, se and df")
    best, best_z, best_parts = 1, -1.0, []
    for k in range(1, n):
        parts = _parts(value, se, df, k, factor)
        change = abs(value[k:].mean() - value[:k].mean())
        var = sum(v for v, _ in parts)
        z = change / np.sqrt(var) if var > 0 else (np.inf if change > 0 else 0.0)
        if z > best_z:
            best, best_z, best_parts = k, z, parts
    estimate = float(value[best:].mean() - value[:best].mean())
    change = from_parts(estimate, best_parts, level, margin)
    return best, replace(change, noise=(_noise(best_parts, n),))
