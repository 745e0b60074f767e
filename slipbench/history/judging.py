"""All of a figure's proposed steps judged at once: the gate's contrast over arrays.

:func:`slipbench.history.steps.step_change` judges one proposal: a contrast of one part (the
seeds' pooled variance, or both rows' test noise where each side holds one seed), its interval,
its state, the p-value of a change within the tolerance and the seeds a side that would decide
it. Each is a few scipy calls on scalars, and a long history proposes thousands of steps; here
every proposal of a figure is one array through the same formulas, in the same order of
operations, so that each number is the one the scalar path gives (``tests/stats/
test_judging.py`` holds them equal).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy  # its stats load on first use

from slipbench.gate.gate import MAX_NEEDED, POWER
from slipbench.stats.contrast import ONE_SEED, TEST_NOISE
from slipbench.store.columns import FIGURES

#: the chance that a series without a step gets a confirmed one (Bonferroni over its proposals)
SERIES_ALPHA = 0.01
#: where a step's seed noise was measured where no other source is given
SEGMENT_SEEDS = "the seeds of the segments beside the step"


@dataclass(frozen=True)
class Side:
    """One segment's seeds (:func:`slipbench.history.steps._seeds`): each seed's value, standard
    error and degrees of freedom."""

    value: np.ndarray
    se: np.ndarray
    df: np.ndarray


def _lesser(x: np.ndarray, cap: float) -> np.ndarray:
    """``min(cap, x)`` as Python reads it: ``cap`` unless ``x < cap`` (so NaN gives ``cap``)."""
    return np.where(x < cap, x, cap)


def _parts(sides: list[tuple[Side, Side]]) -> dict[str, np.ndarray]:
    """Per proposal: its estimate and its one part's variance and degrees of freedom, as
    ``step_change`` builds them (the segments' own seed spread pooled, else test noise)."""
    n = len(sides)
    est, var_b, var_a = np.empty(n), np.full(n, np.nan), np.full(n, np.nan)
    nb, na = np.empty(n, int), np.empty(n, int)
    first = np.empty((n, 4))  # the first seed's se and df on each side
    for i, (b, a) in enumerate(sides):
        est[i] = float(a.value.mean() - b.value.mean())
        nb[i], na[i] = len(b.value), len(a.value)
        if nb[i] > 1:
            var_b[i] = float(np.var(b.value, ddof=1))
        if na[i] > 1:
            var_a[i] = float(np.var(a.value, ddof=1))
        first[i] = (b.se[0], a.se[0], b.df[0], a.df[0])
    keep_b, keep_a = (nb >= 2) & np.isfinite(var_b), (na >= 2) & np.isfinite(var_a)
    own_df = np.where(keep_b, nb - 1, 0) + np.where(keep_a, na - 1, 0)
    alone = own_df == 0
    with np.errstate(invalid="ignore", divide="ignore"):
        own = (
            np.where(keep_b, var_b * (nb - 1), 0.0) + np.where(keep_a, var_a * (na - 1), 0.0)
        ) / own_df
    bad = ~alone & ~(np.isfinite(own) & (own >= 0))
    if bad.any():
        raise ValueError(f"a seed variance is finite and >= 0, got {own[bad][0]}")
    seeds_var = own / np.maximum(1, nb) + own / np.maximum(1, na)
    test_var = first[:, 0] ** 2 + first[:, 1] ** 2
    return {
        "estimate": est,
        "variance": np.where(alone, test_var, seeds_var),
        "df": np.where(alone, np.minimum(first[:, 2], first[:, 3]), own_df.astype(float)),
        "alone": alone,
        "seeds": np.minimum(nb, na),
    }


def judge(
    sides: list[tuple[Side, Side]],
    figure: str,
    margin: float,
    series: tuple[np.ndarray, np.ndarray],
) -> dict[str, np.ndarray]:
    """Every proposal of ``figure``: its change and verdict as :func:`slipbench.history.steps.
    _verdict` and ``_runs_needed`` give them, one array per column.

    Parameters
    ----------
    sides : per proposal, the seeds of the segment before it and after it.
    figure : the figure judged; ``margin`` its tolerance in its stored unit.
    series : per proposal, the proposals of its series (Bonferroni's count over
        :data:`SERIES_ALPHA`) and whether a low-n cell lies in its segments.
    """
    proposals, low_n = np.asarray(series[0], int), np.asarray(series[1], bool)
    p = _parts(sides)
    est, var, df, alone = p["estimate"], p["variance"], p["df"], p["alone"]
    level = 1 - SERIES_ALPHA / np.maximum(1, proposals)
    ok = np.isfinite(var) & (var >= 0) & (df > 0) & np.isfinite(est)
    with np.errstate(invalid="ignore"):
        half = np.sqrt(scipy.stats.t.ppf(0.5 + level / 2, np.where(ok, df, 1.0)) ** 2 * var)
    lo, hi = np.where(ok, est - half, np.nan), np.where(ok, est + half, np.nan)
    se, df = np.where(ok, np.sqrt(var), np.nan), np.where(ok, df, np.nan)
    judged = np.isfinite(est) & np.isfinite(lo) & np.isfinite(hi)
    shown = ~alone & judged & ((lo > margin) | (hi < -margin))
    inside = ~alone & judged & ~shown & (-margin <= lo) & (hi <= margin)
    p_value = _p_beyond(est, se**2, df, margin)
    scale = FIGURES[figure].scale
    held = low_n | alone
    worse = np.where(lo > margin, 1, -1) == FIGURES[figure].worse
    verdict = np.where(
        held,
        "inconclusive",
        np.where(shown, np.where(worse, "regressed", "improved"), "not confirmed"),
    )
    undecided_why = np.where(
        judged, f"its interval holds both a change within ±{margin:g} and one beyond it", ""
    )
    undecided_why = np.where(judged, undecided_why, "no interval")
    why = np.where(
        held,
        np.where(low_n, "low n", ONE_SEED),
        np.where(shown | inside, "", undecided_why),
    )
    needed = np.zeros(len(est), int)
    beyond = np.abs(est) - margin
    with np.errstate(invalid="ignore"):
        open_ = ~shown & ~alone & (beyond > 0) & (se > 0)
    if open_.any():
        spread = (se[open_], df[open_], proposals[open_])
        needed[open_] = _needed(p["seeds"][open_], beyond[open_], spread)
    return {
        "change": est * scale,
        "change_lo": lo * scale,
        "change_hi": hi * scale,
        "se": se * abs(scale),
        "df": df,
        "level": level,
        "tolerance": np.full(len(est), margin * abs(scale)),
        "p_adjusted": np.where(held, 1.0, _lesser(proposals * p_value, 1.0)),
        "noise": np.where(alone, TEST_NOISE, SEGMENT_SEEDS),
        "verdict": verdict,
        "why": why,
        "runs_needed": needed,
    }


def _p_beyond(est: np.ndarray, var: np.ndarray, df: np.ndarray, margin: float) -> np.ndarray:
    """:func:`slipbench.stats.contrast.p_beyond` of one part, over arrays."""
    gap = np.abs(est) - margin
    with np.errstate(invalid="ignore", divide="ignore"):
        tail = 2 * scipy.stats.t.sf(gap / np.sqrt(var), df)
        varies = var > 0
    p = np.where(varies, _lesser(tail, 1.0), 0.0)
    p = np.where(gap <= 0, 1.0, p)
    return np.where(np.isfinite(gap), p, np.nan)


def _resolution(n: np.ndarray, m: np.ndarray, spread: tuple[np.ndarray, ...]) -> np.ndarray:
    """:func:`slipbench.gate.gate.scaled_resolution` of seeds at ``m`` of the ``n`` that ran,
    with :func:`slipbench.gate.gate.resolution` (``spread``: standard errors, degrees of
    freedom, tests), over arrays."""
    se, df, tests = spread
    grow = np.where(n > 1, (m - 1) / np.where(n > 1, n - 1, 1), m / n)
    at_se, at_df = se * np.sqrt(n / m), df * grow
    ok = np.isfinite(at_se) & (at_df > 0)
    safe = np.where(ok, at_df, 1.0)
    t = scipy.stats.t
    q = t.ppf(1 - SERIES_ALPHA / (2 * np.maximum(1, tests)), safe) + t.ppf(POWER, safe)
    return np.where(ok, at_se * q, np.nan)


def _needed(n: np.ndarray, tol: np.ndarray, spread: tuple[np.ndarray, ...]) -> np.ndarray:
    """:func:`slipbench.gate.gate.needed` of every open proposal in lockstep: doubling, then
    bisection, each step one array of quantiles."""
    n = n.astype(float)

    def res(m: np.ndarray, pick: np.ndarray) -> np.ndarray:
        return _resolution(n[pick], m, tuple(x[pick] for x in spread))

    out = np.zeros(len(n), int)
    every = np.arange(len(n))
    start = (n > 0) & np.isfinite(res(n, every))
    lo, hi = np.zeros(len(n)), n.copy()
    grow = start.copy()
    while grow.any():
        i = np.flatnonzero(grow)
        wide = res(hi[i], i) > tol[i]
        done, i = i[~wide], i[wide]
        grow[done] = False
        capped = hi[i] >= MAX_NEEDED
        out[i[capped]], grow[i[capped]] = MAX_NEEDED, False
        i = i[~capped]
        lo[i], hi[i] = hi[i], np.minimum(2 * hi[i], MAX_NEEDED)
    split = start & (out != MAX_NEEDED)
    while (split & (hi - lo > 1)).any():
        i = np.flatnonzero(split & (hi - lo > 1))
        mid = np.floor((lo[i] + hi[i]) / 2)
        fine = res(mid, i) <= tol[i]
        hi[i[fine]], lo[i[~fine]] = mid[fine], mid[~fine]
    done = split
    out[done] = [int(math.ceil(h)) for h in hi[done]]
    return out
