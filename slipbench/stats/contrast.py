"""Every paired change, one way: the contrast of two sides.

Every statement that two things differ (the gate's cells and pooled tests, a leaderboard pair,
"vs baseline", a dataset's change across datasets, a finding of the paper, channels against
univariate) is a :class:`Contrast`: which cells and seeds both sides finished (paired seed by
seed, the rest named as left out), the estimate, its standard error and degrees of freedom, its
interval, and its **state** against a stated margin ``m`` (in the figure's stored unit):

- ``shown``: the interval lies beyond the margin on one side (``lo > m`` or ``hi < -m``): the
  two differ by more than the margin, in the direction of the estimate (:attr:`Contrast.direction`);
- ``contradicted``: the interval lies inside ``[-m, m]``: no difference the margin would count;
  this is the only "no";
- ``undecided``: anything else: no interval, an interval that holds a change within the margin
  and one beyond it, or an interval that lacks a noise the claim needs (:attr:`Contrast.missing`:
  one block, one seed per side).

The verdict reads the interval it shows: a table prints the interval its state used, at the
level its family holds (:func:`family_level`, Bonferroni), never a p-value of another test.

Noise. An interval holds the test trials' noise (from the cells' rows, or one joint cluster
bootstrap over the trials the cells share, :func:`slipbench.stats.pooled.pooled_change`) and,
where the claim reaches over trainings, the seeds' (retraining) noise: a
:class:`~slipbench.stats.noise.SeedNoise` (variance, degrees of freedom, source). Today's sources
are the contrast's own seeds (``OWN_SEEDS``) and the protocol's pooled seed variance
(``PROTOCOL_POOL``); a caller may pass another (``noise=``): a calibration of the bench, the
history of main. Without one, a contrast of one seed per side is undecided, whatever its width.

Intervals from parts (:func:`from_parts`): a variance made of components with their own degrees
of freedom (test trials, blocks, seeds) takes Banerjee's half-width ``sqrt(sum t_i^2 V_i)``,
never narrower than the interval of the component with the fewest degrees of freedom alone
(Banerjee 1961); its standard error is ``sqrt(sum V_i)`` and its degrees of freedom those at
which a t-interval of that standard error is as wide (:func:`effective_df`), so that
``estimate +- t(df) * se`` gives back the interval shown: what :mod:`slipbench.stats.meta` pools.

From rows (:func:`from_rows`, for contrasts of cells without their predictions: a finding of
the paper, "vs baseline" of rows alone): each cell's standard error is its row's, else its 95 %
interval's half-width over z. Cells of one *unit* (those tested on the same test windows) are
combined as independent: their errors move together, and for a contrast whose weights sum to
zero that positive correlation only narrows the true spread, so the independent sum is
conservative. Units are then added by their standard errors (the Minkowski bound, valid whatever
the correlation: fingers share trials). Several seeds: the contrast is taken per seed, and the
mean over seeds gets the seeds' mean standard error (at z) and their spread over the number of
seeds (at t with ``S - 1`` degrees of freedom), combined as Banerjee's.

Measured (``benchmarks/bench_findings_contrast.py``: three fingers recorded in the same trials,
10 and 20 trials per class, 500 replications per setting, against closed-form truths; table in
``docs/studies/coverage.md``), for the window rise, the change beyond window 50, the TP - TN gap and the
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

import json
import os
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd
import scipy  # its stats and optimize load on first use: reading stored rows pays neither

from slipbench.stats.bootstrap import LEVEL, IntervalSpec
from slipbench.stats.metrics import RATES
from slipbench.stats.noise import OWN_SEEDS, SeedNoise, own_seeds
from slipbench.stats.pooled import cell_sides, find_predictions, pooled_change
from slipbench.store.columns import (
    ACCURACY,
    DETECTION_RATE,
    FIGURES,
)
from slipbench.store.resolved import cell_keys, inputs, plain, plain_rows

SHOWN, CONTRADICTED, UNDECIDED = "shown", "contradicted", "undecided"
#: the states that settle a claim one way or the other: "decided" means one of these and
#: nothing else, in every table and count (an interval that holds every noise its claim needs
#: and still straddles the margin is undecided)
DECIDED = (SHOWN, CONTRADICTED)
#: what every contrast's interval holds
TEST_NOISE = "test trials"
#: the claim needs retraining noise and no seed measured it
ONE_SEED = "one seed per side: retraining noise is not in the interval"
#: some cell's row holds no interval of the figure (neither a standard error nor bounds)
NO_ROW_INTERVAL = "no interval in the rows"
#: the note :mod:`slipbench.stats.metrics` writes where a class holds a single test trial
SINGLE_CLUSTER = "a class holds a single cluster"
#: the bootstraps' seed and level where a caller gives none
SEED_0 = IntervalSpec(0)
#: measured coverage of contrasts with one seed per cell where retraining moves a cell's
#: accuracy by about 12 points (module docstring)
ONE_SEED_COVERAGE = "0.72-0.89"


@dataclass(frozen=True)
class Contrast:
    """A paired change (candidate minus base, or A minus B) in the figure's stored unit.

    Attributes
    ----------
    estimate, lo, hi, se, df : its value, its interval at ``level``, standard error and degrees
        of freedom (NaN bounds: no interval).
    level : the interval's level (a family's Bonferroni level, or 0.95 alone).
    margin : the change within which it reads "no difference" (0: none reads so).
    missing : the noise its claim needs and its interval lacks ("" where none): the state is
        then undecided, whatever the interval.
    noise : what its interval holds, in words (test trials, blocks, a seed source).
    n_cells : the cells (or blocks) both sides finished that it pairs.
    seeds : the seeds it pairs (both sides ran each).
    left_out : what one side only finished, or could not be paired, named.
    method : how the interval was drawn.
    """

    estimate: float
    lo: float = np.nan
    hi: float = np.nan
    se: float = np.nan
    df: float = np.nan
    level: float = LEVEL
    margin: float = 0.0
    missing: str = ""
    noise: tuple[str, ...] = ()
    n_cells: int = 0
    seeds: tuple[int, ...] = ()
    left_out: tuple[str, ...] = ()
    method: str = ""

    @property
    def judged(self) -> bool:
        """It has an estimate and an interval."""
        return bool(np.isfinite(self.estimate) and np.isfinite(self.lo) and np.isfinite(self.hi))

    @property
    def state(self) -> str:
        """``shown``, ``contradicted`` or ``undecided`` (module docstring)."""
        if self.missing or not self.judged:
            return UNDECIDED
        return state_of(self.lo, self.hi, self.margin)

    @property
    def decided(self) -> bool:
        """Its interval settles it: shown or contradicted (:data:`DECIDED`)."""
        return self.state in DECIDED

    @property
    def direction(self) -> int:
        """+1 where shown above the margin, -1 below, 0 otherwise."""
        if self.state != SHOWN:
            return 0
        return 1 if self.lo > self.margin else -1

    @property
    def why(self) -> str:
        """Why it is undecided, in words; "" where it is not."""
        if self.state != UNDECIDED:
            return ""
        if self.missing:
            return self.missing
        if not self.judged:
            return "no interval"
        return f"its interval holds both a change within ±{self.margin:g} and one beyond it"

    def scaled(self, factor: float) -> Contrast:
        """The same contrast in other units (``100``: fractions to points)."""
        return replace(
            self,
            estimate=self.estimate * factor,
            lo=self.lo * factor,
            hi=self.hi * factor,
            se=self.se * abs(factor),
            margin=self.margin * abs(factor),
        )


def state_of(lo: float, hi: float, margin: float) -> str:
    """The state of an interval against ``margin`` (module docstring); undecided without one."""
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return UNDECIDED
    if lo > margin or hi < -margin:
        return SHOWN
    if -margin <= lo and hi <= margin:
        return CONTRADICTED
    return UNDECIDED


def is_decided(state: str) -> bool:
    """``state`` settles its claim (:data:`DECIDED`): what every "decided" count counts."""
    return state in DECIDED


def family_level(n: int, alpha: float = 1 - LEVEL) -> float:
    """The level of each of ``n`` intervals that holds them all at once with probability at
    least ``1 - alpha`` (Bonferroni): ``1 - alpha / n``."""
    return 1 - alpha / max(1, n)


def level_text(level: float) -> str:
    """An interval's level in percent with as many decimals as it takes to differ from 100
    ("99.79 %", "99.99974 %"; "95 %"): a look's level is never printed as 100 %."""
    miss = 100 * (1 - level)
    if not miss > 0:  # a look that spends no error flags nothing
        return "no-error (it flags nothing)"
    decimals = max(0, int(np.ceil(-np.log10(miss))) + 1)
    return f"{100 * level:.{decimals}f}".rstrip("0").rstrip(".") + " %"


def margin_of(figure: str) -> float:
    """The stated margin of a contrast of ``figure``, in its stored unit: its tolerance in the
    results schema (the gate's default), else one point of a fraction."""
    declared = FIGURES.get(figure)
    if declared is None:
        return 0.01
    tolerance = declared.tolerance if declared.tolerance is not None else 1.0
    return tolerance / declared.scale


# ----------------------------------------------------------------------------- intervals
def effective_df(half: float, se: float, level: float) -> float:
    """The degrees of freedom at which ``t * se`` is ``half`` wide (inf where a normal interval
    is at least as wide)."""
    q = 0.5 + level / 2
    if not (se > 0 and np.isfinite(half)):
        return np.nan
    ratio = half / se
    if ratio <= scipy.stats.norm.ppf(q) * (1 + 1e-12):
        return np.inf
    return float(scipy.optimize.brentq(lambda d: scipy.stats.t.ppf(q, d) - ratio, 1e-3, 1e9))


def from_parts(
    estimate: float,
    parts: Sequence[tuple[float, float]],
    level: float = LEVEL,
    margin: float = 0.0,
) -> Contrast:
    """A contrast whose variance is a sum of components ``(variance, degrees of freedom)``,
    with Banerjee's interval (module docstring). A component with no degrees of freedom (one
    block, one seed) or no finite variance leaves it without an interval; the caller says why
    (``missing``) and what it pairs (``dataclasses.replace``)."""
    ok = len(parts) > 0 and all(np.isfinite(v) and v >= 0 and df > 0 for v, df in parts)
    if not (ok and np.isfinite(estimate)):
        return Contrast(float(estimate), level=level, margin=margin)
    half = half_width(parts, level)
    se = float(np.sqrt(sum(v for v, _ in parts)))
    if len(parts) == 1:  # its own: no root to find (a history's steps build thousands)
        df = float(parts[0][1])
    else:
        df = effective_df(half, se, level) if se > 0 else np.inf
    return Contrast(float(estimate), estimate - half, estimate + half, se, df, level, margin)


def half_width(parts: Sequence[tuple[float, float]], level: float) -> float:
    """Banerjee's half-width of ``parts`` at ``level``: ``sqrt(sum t_i^2 V_i)``."""
    q = 0.5 + level / 2
    return float(np.sqrt(sum(scipy.stats.t.ppf(q, df) ** 2 * v for v, df in parts)))


def p_beyond(estimate: float, parts: Sequence[tuple[float, float]], margin: float = 0.0) -> float:
    """The p-value of a change within ``margin``: the largest ``1 - level`` at which the
    interval of :func:`from_parts` still reaches the margin on the estimate's side, so that
    ``p < alpha`` exactly where the interval at ``1 - alpha`` is shown beyond it (1 where the
    estimate lies within the margin; 0 where it does not and nothing varies)."""
    gap = abs(estimate) - margin
    if not np.isfinite(gap):
        return np.nan
    if gap <= 0:
        return 1.0
    if not any(v > 0 for v, _ in parts):
        return 0.0
    if len(parts) == 1:  # one component: the t-test's own p-value, no root to find
        ((v, df),) = parts
        return float(min(1.0, 2 * scipy.stats.t.sf(gap / np.sqrt(v), df)))

    def reach(alpha: float) -> float:
        return half_width(parts, 1 - alpha) - gap

    if reach(1 - 1e-12) > 0:
        return 1.0
    if reach(1e-15) < 0:
        return 0.0
    return float(scipy.optimize.brentq(reach, 1e-15, 1 - 1e-12))


def from_rows(
    terms: pd.DataFrame,
    level: float = LEVEL,
    margin: float = 0.0,
    noise: SeedNoise | None = None,
) -> Contrast:
    """The weighted sum of cells' figures from their rows (module docstring).

    Parameters
    ----------
    terms : one line per cell, or per cell and ``seed``: ``unit`` (cells of one unit test the
        same windows), ``weight``, ``mean``, its ``se`` or its 95 % ``lo``/``hi``. With several
        seeds, every seed's lines are the same cells.
    noise : a seed variance from elsewhere (a calibration), taken where the rows hold one seed
        per cell and so no spread of their own.

    Returns
    -------
    Contrast
        ``missing`` says :data:`ONE_SEED` where neither several seeds nor ``noise`` measure
        retraining noise.
    """
    if terms.empty:
        return Contrast(np.nan, level=level, margin=margin, missing="no cell to contrast")
    seeds = tuple(int(s) for s in terms["seed"].dropna().unique()) if "seed" in terms else ()
    groups = [t for _, t in terms.groupby("seed", sort=True)] if len(seeds) > 1 else [terms]
    per = [_one_seed(t) for t in groups]
    values = np.array([v for v, _ in per])
    estimate = float(values.mean())
    if not all(np.isfinite(se) for _, se in per):
        missing = NO_ROW_INTERVAL
        return Contrast(estimate, level=level, margin=margin, missing=missing, seeds=seeds)
    seed_noise = own_seeds(values) or noise
    parts = [(float(np.mean([se for _, se in per])) ** 2, np.inf)]
    said = [TEST_NOISE]
    if seed_noise is not None:
        parts.append((seed_noise.of_mean(len(values)), seed_noise.df))
        said.append(seed_noise.source)
    return replace(
        from_parts(estimate, parts, level, margin),
        missing="" if seed_noise is not None else ONE_SEED,
        noise=tuple(said),
        seeds=tuple(sorted(seeds)),
    )


def _one_seed(terms: pd.DataFrame) -> tuple[float, float]:
    """One seed's (or one summary's) contrast and its standard error (module docstring)."""
    z = float(scipy.stats.norm.ppf(0.5 + LEVEL / 2))
    w = terms["weight"].to_numpy(dtype=float)
    value = float(np.sum(w * terms["mean"].to_numpy(dtype=float)))
    from_bounds = (
        (terms["hi"].to_numpy(dtype=float) - terms["lo"].to_numpy(dtype=float)) / (2 * z)
        if {"lo", "hi"} <= set(terms)
        else np.full(len(terms), np.nan)
    )
    se = terms["se"].to_numpy(dtype=float) if "se" in terms else from_bounds
    se = np.where(np.isfinite(se), se, from_bounds)
    if not np.all(np.isfinite(se)):
        return value, np.nan
    var = pd.Series((w * se) ** 2, index=terms.index).groupby(terms["unit"].to_numpy()).sum()
    return value, float(np.sqrt(var).sum())


# ----------------------------------------------------------------------------- pairing
@dataclass(frozen=True)
class Pairing:
    """Which cells and seeds both sides finished: per cell, the rows of the seeds both ran (in
    seed order, the same on both sides), and what was left out, named."""

    cells: tuple[tuple[str, tuple[dict, ...], tuple[dict, ...]], ...]
    left_out: tuple[str, ...] = ()

    @property
    def seeds(self) -> tuple[int, ...]:
        return tuple(sorted({int(r["seed"]) for _, b, _ in self.cells for r in b}))

    @property
    def low_n(self) -> int:
        """The paired cells where a row rests on few test trials (``low_n``)."""
        return sum(any(bool(plain(r.get("low_n"))) for r in (*b, *c)) for _, b, c in self.cells)


def _finished(rows: pd.DataFrame, figure: str) -> dict[str, dict[int, list[dict]]]:
    """Per cell and seed, the rows that finished with a value of ``figure``."""
    if figure not in rows:
        return {}
    kept = rows[rows["status"] == "ok"] if "status" in rows else rows
    kept = kept[kept[figure].notna()]
    out: dict[str, dict[int, list[dict]]] = {}
    cells = cell_keys(kept)  # resolved rows hold them
    for cell, r in zip(cells, plain_rows(kept).assign(input=inputs(kept)).to_dict("records")):
        seed = plain(r.get("seed"))
        out.setdefault(cell, {}).setdefault(-1 if seed is None else int(seed), []).append(r)
    return out


def pair_seeds(
    base: pd.DataFrame, cand: pd.DataFrame, figure: str = ACCURACY.name, names: Sequence[str] = ()
) -> Pairing:
    """The cells and seeds both ``base`` and ``cand`` finished with a value of ``figure``, kept
    to the seeds every such cell pairs (so that a seed's mean is over the same cells); the
    rest named in :attr:`Pairing.left_out` (``names``: the two sides' names)."""
    who = list(names) or ["BASE", "CANDIDATE"]
    b, c = _finished(base, figure), _finished(cand, figure)
    left: Counter = Counter()
    for side, mine, other in ((who[0], b, c), (who[1], c, b)):
        n = sum(1 for k in mine if k not in other)
        if n:
            left[f"{n} {_cells(n)} only {side} finished"] += 1
    twice = [k for k in b if k in c and _twice(b[k], c[k])]
    if twice:
        left[f"{len(twice)} {_cells(len(twice))} holding a seed stored twice on a side"] += 1
    shared = {k: (b[k], c[k]) for k in b if k in c and k not in twice}
    both = {k: sorted(set(x) & set(y)) for k, (x, y) in shared.items()}
    common = sorted(set.intersection(*(set(s) for s in both.values()))) if both else []
    for side, at in ((who[0], 0), (who[1], 1)):
        lone = Counter(s for k, v in shared.items() for s in v[at] if s not in both[k])
        left.update(_seeds_of(lone, f"{side} only"))
    spare = Counter(s for k in both for s in both[k] if s not in common)
    left.update(_seeds_of(spare, "not paired in every cell"))
    cells = tuple(
        (k, tuple(shared[k][0][s][0] for s in common), tuple(shared[k][1][s][0] for s in common))
        for k in shared
        if common
    )
    return Pairing(cells, tuple(left))


def _unestimable(pairing: Pairing, figure: str, joint: bool) -> str:
    """Why a paired change of ``figure`` has no interval, naming the cells: those whose row says
    its interval is not estimable (a class of a single test trial: the row shows the figure's
    whole range), else those whose row holds none; ``joint``: the joint bootstrap over the
    trials the cells share was not estimable."""
    lone, bare = [], []
    for _, b, c in pairing.cells:
        for r in (*b, *c):
            note = str(plain(r.get("ci_note")) or "")
            name = f"{plain(r.get('protocol')) or ''} {_cell_text(r)}".strip()
            if SINGLE_CLUSTER in note and figure in note.split(":")[0].split(", "):
                lone.append(name)
            elif not any(np.isfinite(_number(r, f"{figure}_{e}")) for e in ("se", "lo", "hi")):
                bare.append(name)
    if lone:
        n = len(set(lone))
        what = "the interval of 1 cell is" if n == 1 else f"the intervals of {n} cells are"
        return (
            f"{what} not estimable (a class holds a single test trial; the row shows the "
            f"figure's whole range): {_some(lone)}"
        )
    if joint:
        return (
            "the joint interval over the paired cells' test trials is not estimable (a class "
            "holds a single test trial)"
        )
    return f"no interval in the row of {_some(bare)}" if bare else NO_ROW_INTERVAL


def _some(names: list[str], shown: int = 3) -> str:
    """The first ``shown`` distinct names, and how many more."""
    names = list(dict.fromkeys(names))
    more = f" and {len(names) - shown} more" if len(names) > shown else ""
    return "; ".join(names[:shown]) + more


def _cell_text(row: dict) -> str:
    """A cell named for a reader: its key's values (``sensor_type=Nano17, window=50``)."""
    text = plain(row.get("cell"))
    try:
        key = json.loads(str(text))
    except (TypeError, ValueError):
        key = None
    if not isinstance(key, dict):
        return str(text or "")
    return ", ".join(f"{k}={v}" for k, v in key.items())


def _seeds_of(counts: Counter, why: str) -> list[str]:
    """``seeds 1, 2 of 4 cells: why``: the seeds left out, those of as many cells together."""
    by_n: dict[int, list[int]] = {}
    for seed, n in sorted(counts.items()):
        by_n.setdefault(n, []).append(seed)
    return [
        f"seed{'s' * (len(seeds) > 1)} {', '.join(map(str, seeds))} of {n} {_cells(n)}: {why}"
        for n, seeds in by_n.items()
    ]


def _number(row: dict, column: str) -> float:
    value = plain(row.get(column))
    return np.nan if value is None else float(value)


def _cells(n: int) -> str:
    return "cell" if n == 1 else "cells"


def _twice(b: dict[int, list[dict]], c: dict[int, list[dict]]) -> bool:
    return any(len(rows) > 1 for rows in (*b.values(), *c.values()))


def summary_figure(rows: pd.DataFrame) -> str:
    """The figure a change of ``rows``' cells is summarised by: accuracy, or a stream's
    detection rate where the rows hold no accuracy."""
    if ACCURACY.name in rows and rows[ACCURACY.name].notna().any():
        return ACCURACY.name
    return DETECTION_RATE.name


def paired_change(
    pairing: Pairing,
    figure: str = ACCURACY.name,
    folders: Sequence[str | os.PathLike] = (),
    spec: IntervalSpec = SEED_0,
    noise: SeedNoise | None = None,
) -> Contrast:
    """The mean over the cells and seeds of ``pairing`` (:func:`pair_seeds`) of (cand - base)
    ``figure`` (as stored: a fraction for rates), at ``spec``'s level, paired seed by seed.

    Where every paired row has its predictions stored (``folders``) and the figure is a rate,
    its interval is one joint cluster bootstrap over the trials the cells share, the seeds
    crossed with the cells and paired (:func:`slipbench.stats.pooled.pooled_change`, seeded by
    ``spec``); else it is from the rows (:func:`from_rows`, each cell a unit of its two sides).
    One seed: the state is undecided (retraining noise is not in the interval; its interval is
    shown), unless ``noise`` (a seed variance from elsewhere, of the seeds' paired differences)
    stands for the seed term.
    """
    seed, level, margin = spec.seed, spec.level, margin_of(figure)
    if not pairing.cells:
        missing = "no cell and seed both finished"
        return Contrast(
            np.nan, level=level, margin=margin, missing=missing, left_out=pairing.left_out
        )
    seeds, n = pairing.seeds, len(pairing.cells)
    paths = [Path(f) for f in folders]
    preds = [
        (
            [find_predictions(paths, str(r["key"])) for r in b],
            [find_predictions(paths, str(r["key"])) for r in c],
        )
        for _, b, c in pairing.cells
    ]
    if figure in RATES and all(p is not None for pb, pc in preds for p in (*pb, *pc)):
        parts = [
            cell_sides(pb, pc, list(b), list(c))
            for (_, b, c), (pb, pc) in zip(pairing.cells, preds)
        ]
        res = pooled_change(parts, seed, level, figure=figure)
        how = "joint cluster bootstrap over the trials the cells share"
        change = Contrast(
            res["d"],
            res["lo"],
            res["hi"],
            res["se"],
            res["df"],
            level,
            margin,
            noise=(TEST_NOISE, *((OWN_SEEDS,) if res["seeds"] else ())),
            method=how + (f", {res['seed_design']}" if res["seeds"] else ""),
        )
        if not res["estimable"]:
            change = replace(change, missing=_unestimable(pairing, figure, joint=True))
    else:
        terms = pd.DataFrame(
            [
                {
                    "unit": k,
                    "seed": plain(r.get("seed")),
                    "weight": sign / n,
                    "mean": float(r[figure]),
                    **{end: _number(r, f"{figure}_{end}") for end in ("se", "lo", "hi")},
                }
                for k, b, c in pairing.cells
                for side, sign in ((b, -1.0), (c, 1.0))
                for r in side
            ]
        )
        how = "from the rows: each cell's two sides as independent, cells as moving together"
        change = replace(from_rows(terms, level, margin), method=how)
    if len(seeds) == 1 and noise is not None and np.isfinite(change.se):
        terms = [(change.se**2, change.df), (noise.of_mean(1), noise.df)]
        added = from_parts(change.estimate, terms, level, margin)
        change = replace(added, noise=(*change.noise, noise.source), method=change.method)
    if change.missing == NO_ROW_INTERVAL:
        change = replace(change, missing=_unestimable(pairing, figure, joint=False))
    # a cell without an interval outweighs the seeds: it says what the change lacks first
    lacks = "" if change.missing in ("", ONE_SEED) else change.missing
    return replace(
        change,
        missing=lacks or ("" if len(seeds) > 1 or noise is not None else ONE_SEED),
        n_cells=n,
        seeds=seeds,
        left_out=pairing.left_out,
    )
