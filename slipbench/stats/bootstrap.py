"""The stratified cluster bootstrap behind every interval of slipbench.

Windows cut from one recording are correlated, so clusters (recordings, or trials several units
recorded at once) are resampled, within their class and balancing stratum: Rao and Wu's
rescaling bootstrap (J. Am. Stat. Assoc. 83, 1988). Figures in [0, 1] take a t-interval on the
logit scale, its standard error at least the replicates' own logit spread; a change takes its
own scale or, where its replicates say so, MOVER on the logit scale (Zou and Donner, Stat. Med.
27, 2008); degrees of freedom are Welch-Satterthwaite's over strata and seed components, or, for a figure
of one seed on few trials, Bell-McCaffrey's from the design (:func:`bell_mccaffrey_df`). Several
seeds add each side's seed variance net of the seed-by-cluster part (:func:`seeded_interval`),
or a seed variance given from elsewhere (:class:`~slipbench.stats.noise.SeedNoise`: the
protocol's cells pooled, a calibration). How each step was chosen and
how well it covers: ``docs/studies/coverage.md`` and ``docs/explanation/statistics.md``; the methods it was chosen
against live in ``benchmarks/studies/intervals.py``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import pandas as pd
import scipy  # scipy.stats loads on first use (see slipbench.stats)

from slipbench.seeding import rng_for
from slipbench.stats.noise import SeedNoise

LEVEL = 0.95
N_RESAMPLES = 999
#: a cell side keeps its own seed spread where it exceeds the protocol's pooled one by more
#: than this quantile of their F ratio (:func:`_noisier`)
NOISIER_QUANTILE = 0.9
#: the methods a command runs: ``scale-choice`` every figure and cell change, ``satterthwaite``
#: the pooled changes (:mod:`slipbench.stats.pooled`); the study methods are in
#: ``benchmarks/studies/intervals.py``
METHODS = ("satterthwaite", "scale-choice")
#: the interval every figure and change takes unless told otherwise (``docs/studies/coverage.md``)
DEFAULT_METHOD = "scale-choice"
#: a method that differs from another only in its changes: the method whose figures it takes
FIGURES_AS = {"scale-choice": "replicate-logit"}


@dataclass(frozen=True)
class ClusterDesign:
    """The clusters of one or more test sets and the strata they are resampled within.

    Attributes
    ----------
    labels : ndarray of shape (n_clusters,)
        The group value of each cluster (a recording id, a trial id).
    stratum : ndarray of shape (n_clusters,)
        The stratum each cluster is resampled within, ``0 .. n_strata - 1``.
    size : ndarray of shape (n_strata,)
        Clusters per stratum.
    """

    labels: np.ndarray
    stratum: np.ndarray
    size: np.ndarray

    @property
    def n_clusters(self) -> int:
        return len(self.labels)

    def lone(self) -> np.ndarray:
        """Shape (n_clusters,): True where a cluster is alone in its stratum, so nothing
        measures how much a cluster like it could have differed."""
        return self.size[self.stratum] < 2

    def df(self, used: np.ndarray) -> int:
        """Clusters minus strata over the strata holding the clusters ``used`` (bool,
        (n_clusters,)): the degrees of freedom of a plain t-interval."""
        strata = np.unique(self.stratum[used])
        return int(max(1, (self.size[strata] - 1).sum()))


def make_design(
    y_true: Sequence[np.ndarray],
    groups: Sequence[np.ndarray],
    strata: Sequence[np.ndarray] | None = None,
) -> tuple[ClusterDesign, list[np.ndarray]]:
    """The joint design of one or more test sets whose clusters may be shared.

    A cluster is a group value; the same value in two test sets is the same cluster (fingers
    recorded in one trial, one recording tested under several seeds), so one resample draws it
    for all of them. Clusters are stratified by class, because a test set's numbers of slip and
    non-slip clusters are fixed by its design, not random. The class of a cluster is slip, non-slip
    or, for a cluster holding windows of both (a continuous trial that holds, then slips; a trial
    id shared by a slip and a non-slip recording), mixed: mixed clusters form a stratum of their
    own, or, when only one exists, join the class holding most of its windows. With ``strata``,
    each class is further split by balancing stratum, a cluster taking the stratum most of its
    windows carry. Strata of a single cluster give no spread to resample, so within a class the
    lone strata are pooled, and a pool that is still alone joins the largest stratum of its
    class. A class of one pure cluster joins the mixed clusters where there are any
    (:func:`_cluster_kinds`); without them it stays alone, and figures that draw on it are not
    estimable.

    Parameters
    ----------
    y_true, groups : sequence of ndarray of shape (n_windows_i,)
        Per test set: labels (1 slip) and each window's cluster.
    strata : sequence of ndarray of shape (n_windows_i,), optional
        Per test set: each window's balancing stratum.

    Returns
    -------
    design : ClusterDesign
    codes : list of ndarray of shape (n_windows_i,)
        Per test set, each window's cluster index into the design.
    """
    if len(y_true) != len(groups) or (strata is not None and len(strata) != len(groups)):
        raise ValueError("y_true, groups and strata must hold one array per test set")
    labels, codes_all = sorted_codes(np.concatenate([np.asarray(g) for g in groups]))
    bounds = np.cumsum([0, *(len(g) for g in groups)])
    codes = [codes_all[a:b] for a, b in zip(bounds[:-1], bounds[1:])]
    y = np.concatenate([np.asarray(v, bool) for v in y_true])
    n = len(labels)
    pos = np.bincount(codes_all, weights=y, minlength=n)
    neg = np.bincount(codes_all, weights=~y, minlength=n)
    kind = _cluster_kinds(pos, neg)
    if strata is None:
        sub = np.full(n, "", dtype=object)
    else:
        s_labels, s_codes = sorted_codes(np.concatenate([np.asarray(s, str) for s in strata]))
        counts = np.zeros((n, len(s_labels)))
        np.add.at(counts, (codes_all, s_codes), 1)
        sub = s_labels[counts.argmax(axis=1)].astype(object)
    key = np.array([f"{k}\x00{s}" for k, s in zip(kind, sub)], dtype=object)
    for k in np.unique(kind):
        in_kind = kind == k
        names, sizes = np.unique(key[in_kind], return_counts=True)
        lone = names[sizes == 1]
        if len(lone) == 0 or len(names) == 1:
            continue
        pooled = f"{k}\x00(pooled lone strata)"
        key[in_kind & np.isin(key, lone)] = pooled
        if len(lone) == 1:  # still alone: into the largest stratum of its class
            key[in_kind & (key == pooled)] = names[sizes > 1][np.argmax(sizes[sizes > 1])]
    _, stratum = np.unique(key, return_inverse=True)
    return ClusterDesign(labels, stratum, np.bincount(stratum)), codes


def _cluster_kinds(pos: np.ndarray, neg: np.ndarray) -> np.ndarray:
    """Each cluster's class stratum from its slip (``pos``) and non-slip (``neg``) windows:
    slip, non-slip or mixed. A lone mixed cluster joins the class holding most of its windows
    (the other, where only that one has pure clusters); a lone pure cluster then joins the clusters holding windows of both classes, which share its
    class (per-sample labels: one trial that only slips among trials that hold, then slip), so
    its class is resampled rather than left alone. Shape (n_clusters,), dtype object."""
    kind = np.where(neg == 0, "slip", np.where(pos == 0, "non-slip", "mixed")).astype(object)
    mixed = kind == "mixed"
    if mixed.sum() == 1:
        pure = {k: int((kind == k).sum()) for k in ("slip", "non-slip")}
        major = "slip" if pos[mixed][0] >= neg[mixed][0] else "non-slip"
        minor = "non-slip" if major == "slip" else "slip"
        # into a class that has clusters to resample it with
        kind[mixed] = minor if pure[major] == 0 and pure[minor] > 0 else major
    if mixed.any():
        for k in ("slip", "non-slip"):
            lone = (kind == k) & ~mixed
            if lone.sum() == 1 and (kind == k).sum() == 1:
                kind[lone] = kind[mixed][0]
    return kind


def sorted_codes(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(values, return_inverse=True)`` by hashing: a pooled test's design holds a
    trial name per window of every cell and seed, and sorting them led ``compare``'s profile."""
    codes, labels = pd.factorize(values, sort=True, use_na_sentinel=False)
    return np.asarray(labels), codes


def resample_weights(
    design: ClusterDesign, seed: int, n_resamples: int = N_RESAMPLES
) -> np.ndarray:
    """Cluster weights of stratified Rao-Wu bootstrap resamples: in a stratum of ``n_h``
    clusters, ``n_h - 1`` drawn with replacement, each weighted ``n_h / (n_h - 1)``; a lone
    cluster keeps weight 1. Read-only: the last two are kept, because every figure of a cell
    draws the same resamples, and drawing them for each figure dominated a cell's statistics
    (``benchmarks/bench_cell_figures.py``); two, so a pooled test's large design is not held.

    Returns
    -------
    ndarray of shape (n_resamples, n_clusters)
    """
    key = (seed, n_resamples, design.stratum.tobytes(), design.size.tobytes())
    if key not in _WEIGHTS:
        while len(_WEIGHTS) >= _KEPT_WEIGHTS:
            del _WEIGHTS[next(iter(_WEIGHTS))]
        _WEIGHTS[key] = _draw_weights(design, seed, n_resamples)
        _WEIGHTS[key].flags.writeable = False
    return _WEIGHTS[key]


_KEPT_WEIGHTS = 2
_WEIGHTS: dict[tuple, np.ndarray] = {}


def _draw_weights(design: ClusterDesign, seed: int, n_resamples: int) -> np.ndarray:
    rng = rng_for(seed, "bootstrap")
    w = np.ones((n_resamples, design.n_clusters))
    for h, n_h in enumerate(design.size):
        if n_h > 1:
            members = np.flatnonzero(design.stratum == h)
            w[:, members] = rng.multinomial(n_h - 1, np.full(n_h, 1 / n_h), size=n_resamples) * (
                n_h / (n_h - 1)
            )
    return w


def satterthwaite_df(
    clusters: Clusters,
    influence: np.ndarray,
    extra: Sequence[tuple[float, float]] = (),
    unsure: float = 0.0,
) -> float:
    """Effective degrees of freedom of a figure's variance.

    Parameters
    ----------
    clusters : the design and the clusters the figure draws on (:class:`Clusters`).
    influence : ndarray of shape (n_clusters,)
        Derivative of the figure by each cluster's weight (its linearization).
    extra : sequence of (variance, df)
        Further independent variance components, e.g. the seed-to-seed variance of a side's
        mean over ``S`` seeds with ``S - 1`` degrees of freedom (:func:`seeded_interval`).
    unsure : float
        ``sum v^2 / df`` of estimates that enter the variance without a component of their own
        (a net seed variance cut at 0 still rests on its spreads): added to the denominator.

    Returns
    -------
    float
        Welch-Satterthwaite over strata and ``extra``, ``(sum V_h)^2 / sum V_h^2 / df_h``, with
        ``V_h`` the stratum's linearized variance and ``df_h`` the smaller of
        ``(n_h - 1) / n_h (sum s^2)^2 / sum s^4`` (the design: unequal cluster sizes) and
        ``3 (n_h - 1) / n_h (sum r^2)^2 / sum r^4`` (the data: ``r`` the clusters' centred
        influences, a plug-in Satterthwaite with normal kurtosis per cluster; it falls when a
        few clusters carry the variance).
    """
    design, used, sizes = clusters.design, clusters.used, clusters.sizes
    num = den = 0.0
    for h, n_h in enumerate(design.size):
        m = (design.stratum == h) & used
        if n_h < 2 or not m.any():
            continue
        r, s = influence[m] - influence[m].mean(), sizes[m]
        v = n_h / (n_h - 1) * (r**2).sum()
        df_h = (n_h - 1) / n_h * (s**2).sum() ** 2 / (s**4).sum()
        if (r**4).sum() > 0:  # a few clusters carrying the variance: fewer still
            df_h = min(df_h, 3 * (n_h - 1) / n_h * (r**2).sum() ** 2 / (r**4).sum())
        num, den = num + v, den + v**2 / df_h
    for v, df_k in extra:
        if v > 0:
            num, den = num + v, den + v**2 / df_k
    den += unsure
    return float(max(1.0, num**2 / den)) if den > 0 else float(design.df(used))


def bell_mccaffrey_df(clusters: Clusters) -> float:
    """Degrees of freedom of a figure's cluster variance from the design alone (Bell and
    McCaffrey, Survey Methodology 28, 2002; Pustejovsky and Tipton, J. Bus. Econ. Stat. 36, 2018).

    Within each stratum a share of windows is a regression on the stratum's intercept; its CR2
    variance scales a cluster's residual total by ``(1 - h_g)^-1/2``, ``h_g = s_g / N_h`` (its
    windows over the stratum's). Under a working model of independent windows of equal
    variance, that variance is a quadratic form with matrix ``A = C (diag(s) - s s' / N_h) C``
    per stratum, ``C = diag((1 - h)^-1/2)``, and Satterthwaite's degrees of freedom are
    ``(tr A)^2 / tr A^2`` over the strata the figure uses: ``n_h - 1`` for clusters of equal size,
    fewer for unequal ones. Unlike the plug-in degrees of freedom of :func:`satterthwaite_df`,
    they do not fall to 1 because one cluster holds the errors (a t quantile of 12.7 made the
    whole range out of 4 trials a class). A figure whose windows weigh differently (the
    balanced accuracy: ``1 / 2 n_class``) gives each cluster its windows' squared weights
    (``clusters.weights``) in place of its windows, so a class of few trials and few windows
    carries its weight in the degrees of freedom too.

    Returns
    -------
    float, at least 1; clusters - strata where no stratum the figure uses has two clusters.
    """
    design, used = clusters.design, clusters.used
    sizes = clusters.sizes if clusters.weights is None else clusters.weights
    trace = square = 0.0
    for h, n_h in enumerate(design.size):
        m = (design.stratum == h) & used
        if n_h < 2 or m.sum() < 2:
            continue
        s = sizes[m].astype(float)
        total = s.sum()
        c = 1 / np.sqrt(1 - np.minimum(s / total, 1 - 1e-9))
        a = c[:, None] * (np.diag(s) - np.outer(s, s) / total) * c[None]
        trace, square = trace + float(np.trace(a)), square + float((a * a).sum())
    if not square > 0:
        return float(design.df(used))
    # rounded: equal clusters give n_h - 1 exactly, not its last bit
    return float(max(1.0, round(trace**2 / square, 9)))


def seed_weights(n_seeds: int, seed: int, side: int, n_resamples: int = N_RESAMPLES) -> np.ndarray:
    """Seed weights of Rao-Wu resamples of one side's seeds (stream ``bootstrap-seeds``):
    ``S - 1`` of ``S`` drawn with replacement, each weighted ``S / (S - 1)``; one seed keeps
    weight 1, so a single seed leaves the cluster bootstrap exactly as it is.

    Returns
    -------
    ndarray of shape (n_resamples, n_seeds)
    """
    if n_seeds < 2:
        return np.ones((n_resamples, max(n_seeds, 1)))
    rng = rng_for(seed, "bootstrap-seeds", side)
    return rng.multinomial(n_seeds - 1, np.full(n_seeds, 1 / n_seeds), size=n_resamples) * (
        n_seeds / (n_seeds - 1)
    )


@dataclass(frozen=True)
class IntervalEstimate:
    """A figure, its interval, its bootstrap standard error, the interval's degrees of freedom,
    and whether the design lets its spread be estimated at all."""

    estimate: float
    lo: float
    hi: float
    se: float
    df: float
    estimable: bool


#: per side, the figure of each seed under cluster weights (n, n_clusters): arrays (n, S_side)
PerSeed = Callable[[np.ndarray], Sequence[np.ndarray]]


@dataclass(frozen=True)
class IntervalSpec:
    """How an interval is drawn: the seed of its resamples, its level, how many resamples, and
    the method (one of METHODS, or a study's :class:`IntervalMethod`).

    The functions that compute figures take these as keywords beside their data
    (``classification_figures(y, pred, groups, seed, level=0.9)``) and build one of them, as a
    command does of its options (:mod:`slipbench.app.options`)."""

    seed: int = 0
    level: float = LEVEL
    n_resamples: int = N_RESAMPLES
    method: str | IntervalMethod = DEFAULT_METHOD
    #: the test set holds fewer than ``LOW_N`` trials of a class: under ``scale-choice`` a
    #: figure of one seed takes :func:`bell_mccaffrey_df` (:func:`_takes_design_df`)
    few_trials: bool = False


@dataclass(frozen=True)
class Clusters:
    """The clusters a figure draws on: the design (strata, clusters), which clusters it uses
    (bool, shape (n_clusters,)) and its windows per cluster (shape (n_clusters,)); optionally
    ``weights``, each cluster's sum of its windows' squared weights in the figure (shape
    (n_clusters,); None: every window weighs alike, as in a share of windows), which
    :func:`bell_mccaffrey_df` reads."""

    design: ClusterDesign
    used: np.ndarray
    sizes: np.ndarray
    weights: np.ndarray | None = None


@dataclass(frozen=True)
class SeededFigure:
    """A figure over seeds (:func:`seeded_interval`): per side, each seed's figure under cluster
    weights and its derivatives by each cluster weight (:data:`PerSeed`; arrays (n, S_k) and
    (n, S_k, n_clusters)); each side's weight in the figure (``signs``: ``(1,)`` for a mean,
    ``(-1, 1)`` for candidate - base); and the range it can take (``bounds``: (0, 1) for
    figures, (-1, 1) for changes)."""

    per_seed: PerSeed
    per_seed_influence: PerSeed
    signs: Sequence[float] = (1.0,)
    bounds: tuple[float, float] = (0.0, 1.0)


def interval(
    statistic: Callable[[np.ndarray], np.ndarray],
    influence: Callable[[np.ndarray], np.ndarray],
    clusters: Clusters,
    spec: IntervalSpec,
    bounds: tuple[float, float] = (0.0, 1.0),
) -> IntervalEstimate:
    """Interval of a figure by the stratified cluster bootstrap.

    Parameters
    ----------
    statistic : callable
        Maps cluster weights of shape (n, n_clusters) to the figure under each row, shape (n,);
        weights of ones give the estimate.
    influence : callable
        Maps weights (n, n_clusters) to the figure's derivative by each weight, same shape.
    clusters : the design, the clusters the figure draws on and its windows per cluster.
    spec.method : one of METHODS, or a study's IntervalMethod
        ``scale-choice`` (the default, :data:`DEFAULT_METHOD`): a figure in (0, 1) takes the
        logit t-interval whose standard error is at least its clusters' replicates' own logit
        spread (:func:`replicate_logit_bounds`); a change of two sides apart, one seed each,
        takes MOVER over its logit level and contrast where its replicates say the contrast is
        steadier on the logit scale (:func:`_takes_mover`); anything else the t-interval with
        Welch-Satterthwaite degrees of freedom, as ``satterthwaite`` does throughout.
    bounds : (low, high)
        The range the figure can take: (0, 1) for figures, (-1, 1) for changes.
    """
    figure = SeededFigure(
        lambda w: [statistic(w)[:, None]], lambda w: [influence(w)[:, None, :]], (1.0,), bounds
    )
    return seeded_interval(figure, clusters, spec)


@dataclass(frozen=True)
class _Replicates:
    """What the resamples of :func:`seeded_interval` give.

    Attributes
    ----------
    cluster : replicates of the seeds' plain means (clusters drawn alone).
    sides : per side, its two-level replicates and the seed-by-cluster variance they hold
        beyond the one count an interval keeps.
    seeded : per side of several seeds: its seed variance of its mean, the seed-by-cluster part
        of it and the seeds' degrees of freedom, each scaled by the side's sign squared.
    """

    cluster: np.ndarray
    sides: list[tuple[np.ndarray, float]]
    seeded: list[tuple[float, float, float]]


def _replicates(
    figures: Sequence[np.ndarray],
    at_one: Sequence[np.ndarray],
    signs: Sequence[float],
    seed: int,
) -> _Replicates:
    """The replicates of every side's figures ``figures`` (n_resamples, S_k) under cluster
    resamples, and each side's seed terms (:class:`_Replicates`)."""
    n_resamples = len(figures[0])
    cluster = np.zeros(n_resamples)
    seeded: list[tuple[float, float, float]] = []
    sides: list[tuple[np.ndarray, float]] = []
    for k, (sign, f) in enumerate(zip(signs, figures)):
        v = seed_weights(f.shape[1], seed, k, n_resamples)
        side = (f * v).sum(axis=1) / v.sum(axis=1)
        cluster += sign * f.mean(axis=1)
        part = 0.0
        if f.shape[1] > 1:
            dev = f - f.mean(axis=1, keepdims=True)
            dev = dev[np.isfinite(dev).all(axis=1)]
            part = float(dev.var(axis=0, ddof=1).mean()) / (f.shape[1] - 1)
            spread = float(at_one[k].var(ddof=1)) / f.shape[1]
            # a side weighted by `sign` contributes sign^2 times its variance
            seeded.append((sign**2 * spread, sign**2 * part, f.shape[1] - 1.0))
        sides.append((side, 2 * part))
    return _Replicates(cluster, sides, seeded)


def _seed_variance(
    reps: _Replicates,
    at_one: Sequence[np.ndarray],
    signs: Sequence[float],
    pool: SeedNoise | None,
) -> tuple[float, float]:
    """The sides' seed variance of their means net of their seed-by-cluster parts (a seed's own
    error on a cluster shows in the seeds' spread and again in the clusters' replicates of
    their mean; counted once, by the clusters), and ``unsure``: the spreads' uncertainty,
    ``sum v^2 / df`` (Satterthwaite for a difference: the net is as uncertain as the spreads it
    is taken from). With ``pool``, a side's spread is the pool's over its seeds, on the pool's
    degrees of freedom (a side of one seed included), unless the side's own spread is larger
    than the pool's beyond chance (:func:`_noisier`): a cell that retraining moves more than the
    protocol's others keeps its own spread on its own degrees of freedom."""
    part = sum(t for _, t, _ in reps.seeded)
    if pool is None:
        spread = sum(v for v, _, _ in reps.seeded)
        return max(0.0, spread - part), sum(v**2 / d for v, _, d in reps.seeded)
    pooled, own, unsure = 0.0, 0.0, 0.0
    for k, f in zip(signs, at_one):
        share = k**2 * pool.variance / len(f)
        mine = k**2 * float(np.var(f, ddof=1)) / len(f) if len(f) > 1 else 0.0
        if _noisier(mine, share, len(f) - 1, pool.df):
            own += mine
            unsure += mine**2 / (len(f) - 1)
        else:
            pooled += share
    # the pooled shares are one estimate: their uncertainty adds before it is squared
    return max(0.0, pooled + own - part), unsure + pooled**2 / pool.df


def _noisier(own: float, pooled: float, df: float, pool_df: float) -> bool:
    """Whether a side's own seed variance ``own`` (on ``df``) exceeds the protocol's ``pooled``
    (on ``pool_df``) beyond chance: their ratio above the F distribution's
    :data:`NOISIER_QUANTILE` (``benchmarks/bench_seed_pool.py``)."""
    if df < 1 or not own > pooled:
        return False
    return bool(own > pooled * scipy.stats.f.ppf(NOISIER_QUANTILE, df, pool_df))


@dataclass(frozen=True)
class Problem:
    """What :func:`seeded_interval` is asked (its parameters, as one record)."""

    per_seed: PerSeed
    per_seed_influence: PerSeed
    signs: tuple[float, ...]
    design: ClusterDesign
    used: np.ndarray
    sizes: np.ndarray
    seed: int
    level: float
    n_resamples: int
    bounds: tuple[float, float]
    weights: np.ndarray | None = None  # as Clusters.weights


@dataclass(frozen=True)
class Fit:
    """One interval's ingredients, from which a method draws its bounds (:func:`_bounds`; a
    study's :class:`IntervalMethod`)."""

    problem: Problem
    est: float
    se: float
    df: float
    reps: _Replicates
    at_one: Sequence[np.ndarray]  # per side, each seed's figure on the test set itself
    level_df: Callable[[], float]  # the df of the two sides' mean (MOVER's level)
    seed_var: float  # the net seed variance inside ``se``

    @property
    def level(self) -> float:
        return self.problem.level

    @property
    def bounds(self) -> tuple[float, float]:
        return self.problem.bounds

    @property
    def signs(self) -> tuple[float, ...]:
        return self.problem.signs

    @property
    def unit(self) -> bool:
        return self.bounds == (0.0, 1.0)

    @property
    def one_side(self) -> bool:
        """A figure in (0, 1) of one side (no change)."""
        return self.unit and self.signs == (1.0,) and 0 < self.est < 1

    @property
    def seed_windows(self) -> float:
        """One seed's windows: the logits' smoothing."""
        p = self.problem
        return float(p.sizes[p.used].sum()) / len(self.at_one[0])

    def logit_t(self) -> tuple[float, float]:
        """The t-interval, on the logit scale for a figure in (0, 1)."""
        q = scipy.stats.t.ppf(1 - (1 - self.level) / 2, self.df)
        est, se = self.est, self.se
        if self.unit and 0 < est < 1:
            z, s = np.log(est / (1 - est)), se / (est * (1 - est))
            return float(1 / (1 + np.exp(-(z - q * s)))), float(1 / (1 + np.exp(-(z + q * s))))
        return est - q * se, est + q * se


class IntervalMethod(Protocol):
    """An interval method of a study (``benchmarks/studies/intervals.py``, ``docs/studies/coverage.md``),
    given to :func:`seeded_interval` in place of a name of :data:`METHODS`."""

    @property
    def name(self) -> str: ...

    @property
    def plain_df(self) -> bool:
        """Take clusters - strata degrees of freedom, not Welch-Satterthwaite's."""
        ...

    def bounds(self, fit: Fit) -> tuple[float, float]:
        """The interval of a figure or change with spread (``fit.se > 0``), before clipping."""
        ...


def _no_spread(fit: Fit, n_used: int) -> tuple[float, float]:
    """No spread: a figure takes the Clopper-Pearson interval with the clusters as the sample
    (the worst case); a change stays a point."""
    if not fit.unit:
        return fit.est, fit.est
    alpha, x = 1 - fit.level, fit.est * n_used
    lo = scipy.stats.beta.ppf(alpha / 2, x, n_used - x + 1) if x > 0 else 0.0
    hi = scipy.stats.beta.ppf(1 - alpha / 2, x + 1, n_used - x) if x < n_used else 1.0
    return float(lo), float(hi)


def _takes_mover(fit: Fit) -> bool:
    """``scale-choice``: a change of two sides apart, one seed each, takes MOVER where the
    replicates say the contrast is steadier on the logit scale (with 3 seeds apart, MOVER over
    the two-level replicates raised 8 of 20 false alarms in compare's null study, the seed terms
    below 0 of 20)."""
    return (
        fit.bounds == (-1.0, 1.0)
        and fit.signs == (-1.0, 1.0)
        and not fit.reps.seeded
        and fit.seed_var == 0
        and _logit_is_steadier(fit.reps.sides, fit.seed_windows)
    )


def replicate_logit_bounds(fit: Fit) -> tuple[float, float]:
    """A figure in (0, 1) as ``scale-choice`` takes it: the logit t-interval over the clusters'
    replicates of the seeds' plain mean (seed draws left out, so several seeds' logit spread is
    the test sets' alone and identical seeds give one seed's interval)."""
    return logit_bounds(fit.reps.cluster, 0.0, fit, fit.seed_windows)


def _bounds(fit: Fit, method: str) -> tuple[float, float]:
    """The interval of ``method`` (one of :data:`METHODS`) with spread (``fit.se > 0``)."""
    if method == "scale-choice" and fit.one_side:
        return replicate_logit_bounds(fit)
    if method == "scale-choice" and _takes_mover(fit):
        return mover_change_bounds(fit)
    return fit.logit_t()


def seeded_interval(
    figure: SeededFigure,
    clusters: Clusters,
    spec: IntervalSpec,
    seed_pool: SeedNoise | None = None,
) -> IntervalEstimate:
    """Interval of ``sum_k signs[k] * (mean over side k's seeds of its figure)`` over trials and
    seeds: its variance is the clusters' (each resample draws clusters once for every seed of
    every side, stratified Rao-Wu, :func:`resample_weights`; the seeds' plain mean under each)
    plus each side's seed variance of its mean, ``var(seed figures) / S_k``, net of the
    seed-by-cluster part the clusters already count. So retraining noise (seed to seed) and
    test-set noise (cluster to cluster) are both inside the interval, each once. Two-level
    replicates (each side's seeds drawn too, Rao-Wu, :func:`seed_weights`) serve the
    ``percentile`` reference and the study methods.

    Parameters
    ----------
    figure : :class:`SeededFigure`
        ``per_seed`` maps cluster weights (n, n_clusters) to a sequence, one per side, of
        arrays (n, S_k): each seed's figure; ``per_seed_influence`` the same for the
        derivatives by each cluster weight: arrays (n, S_k, n_clusters). ``signs``: per side,
        its weight in the figure; any other weight than 1 scales that side's figure and its
        variance components alike.
    clusters, spec : the clusters the figure draws on (:class:`Clusters`), how the interval
        is drawn (:class:`IntervalSpec`).
    seed_pool : SeedNoise, optional
        A seed variance from elsewhere (the protocol's cells pooled,
        :func:`~slipbench.stats.noise.pool_seed_spreads`; a calibration): it replaces the sides'
        own seed spreads, with its degrees of freedom.

    Degrees of freedom: the strata's components (:func:`satterthwaite_df`) and the sides' net
    seed variance, whose degrees of freedom are those of a difference, ``net^2 / sum_k
    v_k^2 / (S_k - 1)`` (``v_k`` a side's seed variance of its mean), combined by
    Welch-Satterthwaite: three seeds leave at most two degrees of freedom to a seed-dominated
    variance, fewer the more the net subtracts; a pool leaves its own. With one seed per side
    and no pool this is exactly the one-level interval of :func:`interval`.
    """
    per_seed, per_seed_influence, signs = figure.per_seed, figure.per_seed_influence, figure.signs
    design, used, sizes = clusters.design, clusters.used, clusters.sizes
    seed, level, n_resamples, method = spec.seed, spec.level, spec.n_resamples, spec.method
    bounds = figure.bounds
    if isinstance(method, str) and method not in METHODS:
        raise ValueError(f"unknown interval method {method!r}; choose one of: {', '.join(METHODS)}")
    problem = Problem(
        per_seed, per_seed_influence, tuple(map(float, signs)), design, used, sizes,
        seed, level, n_resamples, bounds, clusters.weights,
    )  # fmt: skip
    one = np.ones((1, design.n_clusters))
    with np.errstate(invalid="ignore", divide="ignore"):  # a figure the test set lacks is NaN
        at_one = [np.asarray(f)[0] for f in per_seed(one)]
        est = float(sum(k * f.mean() for k, f in zip(signs, at_one)))
    if not np.isfinite(est):
        return IntervalEstimate(est, np.nan, np.nan, np.nan, np.nan, False)
    if used.sum() < 2 or design.lone()[used].any():  # one cluster: nothing measures a spread
        return IntervalEstimate(est, bounds[0], bounds[1], np.nan, np.nan, False)
    with np.errstate(invalid="ignore", divide="ignore"):
        w = resample_weights(design, seed, n_resamples)
        reps = _replicates(per_seed(w), at_one, signs, seed)
    net, unsure = _seed_variance(reps, at_one, signs, seed_pool)
    # `unsure` stays in the denominator where the net is cut at 0 too: seeds that happen to
    # agree do not earn the clusters' degrees of freedom (docs/studies/coverage.md)
    extra = [(net, np.inf)] if net > 0 else []
    # the clusters' variance of the seeds' plain means plus the seeds' own: the two-level
    # replicates' variance holds the seed-by-cluster term three times (seed spread, clusters,
    # and the clusters' spread of the drawn seeds' mean), which no single subtraction undoes
    cluster = reps.cluster[np.isfinite(reps.cluster)]
    se = float(np.sqrt(np.var(cluster, ddof=1) + net))
    side_infl = [np.asarray(g)[0].mean(axis=0) for g in per_seed_influence(one)]
    if getattr(method, "plain_df", False):
        df = float(design.df(used))
    elif spec.few_trials and _takes_design_df(method, problem, at_one, seed_pool):
        df = bell_mccaffrey_df(clusters)
    else:
        infl = sum(k * g for k, g in zip(signs, side_infl))
        df = satterthwaite_df(clusters, np.asarray(infl), extra, unsure)

    def level_df() -> float:  # the two sides' mean, MOVER's level
        mean_infl = np.asarray(sum(side_infl)) / 2
        quarter = [(v / 4, d) for v, d in extra]
        return satterthwaite_df(clusters, mean_infl, quarter, unsure / 16)

    fit = Fit(problem, est, se, df, reps, at_one, level_df, net)
    if se == 0:
        lo, hi = _no_spread(fit, int(used.sum()))
    elif isinstance(method, str):
        lo, hi = _bounds(fit, method)
    else:
        lo, hi = method.bounds(fit)
    lo, hi = float(max(lo, bounds[0])), float(min(hi, bounds[1]))
    return IntervalEstimate(est, lo, hi, se, df, True)


def _takes_design_df(
    method: str | IntervalMethod,
    problem: Problem,
    at_one: Sequence[np.ndarray],
    seed_pool: SeedNoise | None,
) -> bool:
    """``scale-choice`` on few trials (:attr:`IntervalSpec.few_trials`): a figure of one seed
    (no change, no seed variance) takes :func:`bell_mccaffrey_df`, not the plug-in
    :func:`satterthwaite_df`, whose kurtosis term falls to 1 when one of a few trials holds the
    errors; its standard error stays the bootstrap's. Below ``LOW_N`` trials a class the plug-in
    overcovers with whole-range intervals; from 10 trials up it covers better than
    Bell-McCaffrey's, and the CR2 standard error falls short at 5 trials with unequal trials
    (``docs/studies/coverage.md``, "Small test sets"). Seeds and changes keep the plug-in: their
    coverage was measured with it."""
    return (
        method == "scale-choice"
        and problem.bounds == (0.0, 1.0)
        and problem.signs == (1.0,)
        and all(len(f) == 1 for f in at_one)
        and seed_pool is None
    )


def _smoothed_logit(p: np.ndarray | float, n: float) -> np.ndarray:
    """The empirical logit of a figure over ``n`` windows, ``(p n + 1/2) / (n + 1)``: finite at
    0 and 1, where a replicate of nothing but perfect clusters would otherwise lie."""
    q = (np.asarray(p, float) * n + 0.5) / (n + 1)
    return np.log(q / (1 - q))


def _logit_sd(reps: np.ndarray, est: float, n: float, excess: float = 0.0) -> float:
    """Standard error on the logit scale from Rao-Wu replicates of a figure in [0, 1]: the larger
    of their delta-method SD (linear in the replicates) and the SD of their logits, net of the
    seed-by-cluster variance ``excess`` (on the figure's scale) they hold beyond one count."""
    slope = 1 / (est * (1 - est)) if 0 < est < 1 else 4.0 * (n + 1)
    var = max(float(np.var(reps * slope, ddof=1)), float(np.var(_smoothed_logit(reps, n), ddof=1)))
    return float(np.sqrt(max(var - excess * slope**2, 0.0)))


def logit_bounds(reps: np.ndarray, excess: float, fit: Fit, n: float) -> tuple[float, float]:
    """A figure in (0, 1) as ``scale-choice`` (and the studies' ``mover``) takes it: the logit
    t-interval whose standard error is the larger of ``fit``'s (delta method) and
    :func:`_logit_sd` of ``reps`` (net of ``excess``). A rate near its bound whose clusters happen to be good shows a small
    spread; its replicates' logits still reach as far as its worst clusters take them."""
    est = fit.est
    reps = reps[np.isfinite(reps)]
    z = float(np.log(est / (1 - est)))
    s = max(fit.se / (est * (1 - est)), _logit_sd(reps, est, n, excess))
    q = scipy.stats.t.ppf(1 - (1 - fit.level) / 2, fit.df)
    return float(1 / (1 + np.exp(-(z - q * s)))), float(1 / (1 + np.exp(-(z + q * s))))


def _logit_is_steadier(sides: Sequence[tuple[np.ndarray, float]], n: float) -> bool:
    """Method ``scale-choice``: whether a change of two rates is steadier on the logit scale than
    on its own, judged by the replicates: on the scale where the contrast moves less with the
    level (|correlation| of their replicates), the contrast is what the two sides share. A
    candidate that separates the classes better changes the odds alike at every level (logit);
    trials that fail both sides alike shift both rates by the same amount (the rate's own)."""
    (rb, _), (rc, _) = sides
    ok = np.isfinite(rb) & np.isfinite(rc)
    rb, rc = rb[ok], rc[ok]
    zb, zc = _smoothed_logit(rb, n), _smoothed_logit(rc, n)
    with np.errstate(invalid="ignore", divide="ignore"):
        own = abs(float(np.corrcoef(rc - rb, rc + rb)[0, 1]))
        logit = abs(float(np.corrcoef(zc - zb, zc + zb)[0, 1]))
    return bool(np.isfinite(own) and np.isfinite(logit) and logit < own)


def mover_change_bounds(fit: Fit) -> tuple[float, float]:
    """A change candidate - base of figures in [0, 1]: MOVER (Zou and Donner,
    Stat. Med. 27, 2008) over the change's two nearly independent parts on the logit scale,
    the contrast ``delta = logit(cand) - logit(base)`` and the level ``lambda`` (their mean):
    the change is ``f(lambda, delta) = expit(lambda + delta / 2) - expit(lambda - delta / 2)``.

    Each part gets a logit t-interval (standard error :func:`_logit_sd` of its replicates; the
    contrast with the change's degrees of freedom, the level with its own, ``fit.level_df``),
    mapped to the change's scale with the other part held at its estimate; the two arms on each
    side combine as MOVER does, with the correlation of the parts' replicates. A level near a
    bound shrinks a change and its spread together; the level's interval says how far it may be
    off, and so how much larger the change may be. Combining the two sides' own intervals
    instead (MOVER on base and candidate) overcovers: their replicates correlate near 1."""
    est, level, dfs = fit.est, fit.level, (fit.df, fit.level_df())
    means = [float(f.mean()) for f in fit.at_one]
    n = fit.seed_windows * len(fit.at_one[0])
    (rb, tb), (rc, tc) = fit.reps.sides
    ok = np.isfinite(rb) & np.isfinite(rc)
    rb, rc = rb[ok], rc[ok]
    lb, lc = _smoothed_logit(np.array(means), n)
    lam, dlt = (lb + lc) / 2, lc - lb
    zb, zc = _smoothed_logit(rb, n), _smoothed_logit(rc, n)

    def net(rep: np.ndarray, lin: np.ndarray, seed_part: float) -> float:
        var = max(float(np.var(rep, ddof=1)), float(np.var(lin, ddof=1)))
        return float(np.sqrt(max(var - seed_part, 0.0)))

    # the linearization of each side's logit, and the seed-by-cluster excess on the logit scale
    slope = [1 / max(p * (1 - p), 1 / (4.0 * (n + 1))) for p in means]
    gb, gc = (rb - means[0]) * slope[0], (rc - means[1]) * slope[1]
    parts = tb * slope[0] ** 2 + tc * slope[1] ** 2
    s_dlt = net(zc - zb, gc - gb, parts)
    s_lam = net((zc + zb) / 2, (gc + gb) / 2, parts / 4)
    rho = float(np.corrcoef(zc + zb, zc - zb)[0, 1]) if s_dlt > 0 and s_lam > 0 else 0.0
    rho = rho if np.isfinite(rho) else 0.0

    def f(lam_: np.ndarray | float, dlt_: np.ndarray | float) -> np.ndarray:
        return 1 / (1 + np.exp(-(lam_ + dlt_ / 2))) - 1 / (1 + np.exp(-(lam_ - dlt_ / 2)))

    alpha = 1 - level
    q_dlt, q_lam = (scipy.stats.t.ppf(1 - alpha / 2, d) for d in dfs)
    at = float(f(lam, dlt))
    up_c = float(f(lam, dlt + q_dlt * s_dlt)) - at  # f rises with the contrast
    down_c = at - float(f(lam, dlt - q_dlt * s_dlt))
    # f(., delta) is unimodal in the level, peaking at lambda = 0: its extremes over the
    # level's interval lie at an end or at 0
    ends = [lam - q_lam * s_lam, lam + q_lam * s_lam]
    grid = np.array([*ends, *([0.0] if ends[0] < 0 < ends[1] else [])])
    moved = f(grid, dlt) - at
    up_l, down_l = max(float(moved.max()), 0.0), max(float(-moved.min()), 0.0)
    # the parts' arms move the change together when the change rises with the level
    r = rho * float(np.sign(f(lam + 1e-6, dlt) - f(lam - 1e-6, dlt)))
    hi = est + np.sqrt(max(up_c**2 + up_l**2 + 2 * r * up_c * up_l, 0.0))
    lo = est - np.sqrt(max(down_c**2 + down_l**2 + 2 * r * down_c * down_l, 0.0))
    return float(lo), float(hi)
