"""The stratified cluster bootstrap behind every interval of slipbench.

Windows cut from one recording are correlated, so the unit of resampling is the cluster (a
recording, or a trial that several units recorded at once), never the window; and a test set
holds a fixed number of slip and non-slip clusters, so clusters are resampled within their class
(and balancing stratum, when given). The interval is built in three steps, each chosen by
measuring coverage (``tests/stats/test_coverage.py``):

1. **Standard error**: Rao and Wu's rescaling bootstrap (J. Am. Stat. Assoc. 83, 1988): in a
   stratum of ``n_h`` clusters draw ``n_h - 1`` with replacement and weight them
   ``n_h / (n_h - 1)``. The textbook bootstrap (draw ``n_h``) shrinks the variance by
   ``(n_h - 1) / n_h``, a quarter at four recordings per class.
2. **Scale**: figures bounded by 0 and 1 (rates, balanced accuracy, AUROC) take a t-interval on
   the logit scale mapped back, so the interval reaches further towards 0.5 than towards the
   bound, as the skewed sampling distribution of a rate near 1 does. Its standard error is the
   larger of the delta method's (``se / (p (1 - p))``) and the SD of the replicates' own
   logits (method ``replicate-logit``, the default's figures): a rate near its bound whose
   sample holds few poor clusters shows a small spread on its own scale, while its replicates'
   logits still reach as far as its worst clusters take them. Changes (candidate - base) take
   the t-interval on their own scale or, with one seed per side, where the replicates say the
   contrast is steadier on the logit scale (a candidate that changes the odds alike at every
   level), MOVER over the logit level and contrast (method ``scale-choice``, the default since
   it lifted every short change of the study, below).
3. **Degrees of freedom**: Welch-Satterthwaite (:func:`satterthwaite_df`). Within a stratum,
   recordings of unequal length do not weigh alike: when within-recording correlation
   dominates, a cluster's share of the variance grows with its window count squared, so the
   variance rests on ``(sum s^2)^2 / sum s^4`` effective clusters (``s``: windows per cluster),
   about 0.58 ``n_h`` for lengths spread 10-200; fewer still when a few clusters carry the
   observed variance. Strata combine by their linearized variance contributions.

A figure whose resamples show no spread (every recording perfect) gets the Clopper-Pearson
interval with the clusters as the sample (the worst case: each recording one observation), not
a zero-width one. A class with a single cluster leaves nothing to measure how its clusters
vary: figures drawing on it are flagged ``estimable=False`` and get their whole range ([0, 1],
or [-1, 1] for changes), never NaN.

Measured coverage of 95 % intervals, 1,000 simulated test sets per setting, two classes of ``m``
recordings each, window counts 10-200 (slip) and 5-100 (non-slip); ``tau`` is the per-recording
random effect: 0.5 gives an intra-recording correlation of hits of 0.14-0.18, 1.5 of 0.41-0.47
(cells of real BioTac SP and of simulated Holweg results measured 0.05-0.52). ``d``: the paired
change between two detectors on the same windows (compare). Model: ``tests/stats/test_coverage.py``;
measured with the default method (``scale-choice``; the figures are ``replicate-logit``'s),
``python tests/stats/test_coverage.py 1000``, about 20 minutes beside other work. The earlier
tables, measured with ``satterthwaite`` (then the default), had the TN rate at 0.889 (10
recordings, tau 1.5) and 0.914-0.934 at 8-40, the AUROC at 0.917-0.928 at 4-10 (tau 1.5) and
0.920 at 40 with strata.

    ===  ===  =====  =====  =====  =====  =====  =====  =====  =====  =====  =======
      m  tau  acc    TP     TN     BA     AUROC  d acc  d TP   d TN   d BA   d AUROC
    ===  ===  =====  =====  =====  =====  =====  =====  =====  =====  =====  =======
      4  0.5  .965   .981   .992   .970   .971   .971   .985   .982   .982   .997
      6  0.5  .959   .969   .980   .957   .962   .977   .984   .972   .976   .992
      8  0.5  .954   .957   .969   .954   .956   .961   .956   .967   .957   .981
     10  0.5  .941   .948   .968   .954   .949   .968   .975   .965   .969   .981
     20  0.5  .951   .950   .945   .953   .949   .966   .966   .955   .971   .978
     40  0.5  .955   .956   .945   .954   .950   .959   .959   .960   .957   .956
      4  1.5  .976   .977   .990   .977   .927   .975   .973   .839   .987   .999
      6  1.5  .953   .970   .954   .956   .928   .964   .968   .888   .985   1.000
      8  1.5  .958   .963   .944   .963   .940   .965   .958   .914   .977   .993
     10  1.5  .961   .959   .925   .961   .945   .957   .962   .931   .964   .989
     20  1.5  .957   .963   .951   .952   .955   .961   .959   .947   .969   .988
     40  1.5  .956   .950   .943   .954   .951   .958   .954   .955   .957   .971
    ===  ===  =====  =====  =====  =====  =====  =====  =====  =====  =====  =======

The same with two balancing strata per class of different rates, passed as ``strata``:

    ===  ===  =====  =====  =====  =====  =====  =====  =====  =====  =====  =======
      m  tau  acc    TP     TN     BA     AUROC  d acc  d TP   d TN   d BA   d AUROC
    ===  ===  =====  =====  =====  =====  =====  =====  =====  =====  =====  =======
      4  0.5  .979   .980   .983   .979   .988   .986   .979   .975   .987   .994
      6  0.5  .978   .988   .982   .987   .980   .979   .986   .980   .983   .989
      8  0.5  .967   .972   .974   .968   .957   .971   .974   .971   .966   .986
     10  0.5  .968   .975   .958   .976   .970   .974   .982   .963   .977   .984
     20  0.5  .951   .949   .954   .951   .948   .962   .957   .972   .962   .969
     40  0.5  .961   .954   .943   .954   .951   .948   .948   .956   .948   .954
      4  1.5  .983   .983   .996   .983   .981   .981   .967   .874   .990   .998
      6  1.5  .967   .979   .988   .974   .961   .993   .986   .931   .988   .999
      8  1.5  .968   .979   .966   .971   .951   .976   .971   .933   .985   .998
     10  1.5  .972   .975   .962   .975   .960   .978   .973   .936   .984   .997
     20  1.5  .945   .939   .949   .954   .956   .958   .953   .967   .967   .991
     40  1.5  .949   .952   .941   .944   .931   .964   .964   .940   .957   .967
    ===  ===  =====  =====  =====  =====  =====  =====  =====  =====  =====  =======

Pooled over m >= 10 and both correlation levels (without / with strata): accuracy 0.954 /
0.958, TP rate 0.954 / 0.957, TN rate 0.946 / 0.951, balanced accuracy 0.955 / 0.959, AUROC
0.950 / 0.953; changes: accuracy 0.962 / 0.964, TP rate 0.962 / 0.963, TN rate 0.952 / 0.956,
balanced accuracy 0.964 / 0.966, all within the 93-97 % target (under ``replicate-logit``,
whose changes are ``satterthwaite``'s: 0.958 / 0.961, 0.954 / 0.958, 0.933 / 0.942, 0.961 /
0.964); the change in AUROC overcovers (0.977 / 0.977; 0.985 / 0.983 before), but only because
its truth in this model is 0 (the two detectors rank alike: its estimate and its standard error
rise together, so its studentized spread is narrower than t's); where a candidate ranks better
it falls short (``ranks`` below). Single settings fall short under strong correlation: the
change in TN rate at 8 recordings and fewer (0.839-0.914 / 0.874-0.933; at 10 it was 0.870 /
0.895 and is 0.931 / 0.936), the TN rate at 10 (0.925, without strata), where a few recordings
fail badly and most pass perfectly; a sample that happens to hold none of the failing recordings shows no spread, and no
interval built from the recordings at hand can know of them. With few recordings per balancing
stratum the intervals widen (few degrees of freedom) and overcover. Below 10 clusters per class
cells are flagged ``low_n`` (:func:`slipbench.stats.metrics.is_low_n`).

How the method was chosen: exploratory runs, 300 test sets per setting, coverage at m = 10
(tau 0.5 / 1.5) of accuracy, TN rate, AUROC and the change in TN rate:

==============================================  =========  =========  =========  =========
method                                          accuracy   TN rate    AUROC      d TN rate
==============================================  =========  =========  =========  =========
before: percentile, not stratified              .87 / .87  .82 / .71  .85 / .81  .86 / .74
percentile, stratified, textbook bootstrap      .87 / .85  .81 / .71  .84 / .81  .87 / .74
percentile, Rao-Wu                              .87 / .87  .83 / .72  .86 / .83  .88 / .75
BCa, Rao-Wu (jackknife acceleration)            .90 / .90  .85 / .76  .89 / .90  .87 / .75
studentized (linearized SE per resample) [1]    .92 / .96  .91 / .59  .93 / .97  .90 / .58
t, df = clusters - strata                       .88 / .88  .85 / .72  .84 / .79  .93 / .85
logit t (delta), df = clusters - strata         .91 / .92  .92 / .84  .91 / .91  .93 / .85
logit t (SD of logit replicates) [2]            .92 / .94  .95 / .98  .92 / .95  .93 / .85
Korn-Graubard (Clopper-Pearson, effective n)    .91 / .93  .91 / .83  .92 / .91  .93 / .85
logit t (delta), Satterthwaite df: chosen       .93 / .94  .94 / .91  .92 / .94  .95 / .88
==============================================  =========  =========  =========  =========

[1] a resample of perfect recordings has no standard error, so its pivot is infinite and the
interval is lost; [2] overcovers erratically (0.98-0.99 at four recordings): resamples near the
bound blow up on the logit scale. The percentile and plain t intervals stay available
(``method=``) as the references the study compares against.

**Seeds and failing trials** (``benchmarks/bench_coverage.py``, table in ``docs/coverage.md``,
1,000 replications per setting, trial effect SD 1.0, 5-40 trials per class). Several seeds of a
cell or of each side of a change take :func:`seeded_interval`: the clusters' variance of the
seeds' plain means (clusters drawn once for every seed of both sides) plus the sides' seed
variance of their means net of the seed-by-cluster part, which the clusters already count; the
net enters the Satterthwaite sum with the degrees of freedom of a difference. One seed per side
gives exactly the one-level interval. At
10-40 trials per class, accuracy, TP rate and balanced accuracy cover 0.939-0.970 in all three
scenarios (normal; 10 % of trials failing wholesale; 3 seeds with a random effect on
performance); the TN rate 0.895-0.953 (short near its bound: 0.90-0.92 in the normal and
heavy-tailed scenarios), the AUROC 0.929-0.966 except 0.885 with failing trials at 10 (12 % of
those test sets hold no failing trial at all, and no interval from the sample can reach the
truth then), the change in TN rate 0.915-0.975. The change in AUROC, whose truth in these
three is 0, overcovers, 0.96-1.00 (0.98-1.00 at 10-20 trials); the changes with 3 seeds at 10
trials covered 0.975-0.979 while the seed-by-cluster variance was counted three times,
0.953-0.970 once it was counted once, and 0.979-0.986 since a net cut at 0 keeps its
spreads' uncertainty (over the band, the price of a null study of paired seeds at 0 of 20;
figures 0.936-0.974). A skewness correction of the
t-interval (each side widened to the bootstrap's own tail) did not help (300 replications); the default stays. A fourth scenario,
``ranks`` (a candidate that ranks better, so the change in AUROC is +0.036, not 0), shows the
default short for the changes in AUROC and TN rate (0.84-0.88 at 10-20 trials per class,
0.90-0.92 at 40). ``method="mover"`` fixes those (0.936-0.949) but overcovers the changes with
failing trials (0.975-1.000); ``method="replicate-logit"``, its figure part alone, lifts the TN
rate and AUROC (normal TN 0.910-0.922 -> 0.926-0.945) and crosses 97 % in one cell (0.973);
``docs/coverage.md`` gives the screening and the choice. ``replicate-logit`` is the default
now (figures as good as ``satterthwaite``'s or better in every cell of the study within its
noise; changes exactly ``satterthwaite``'s); the tables above were measured with
``satterthwaite``. ``scale-choice`` is the default since (its figures ``replicate-logit``'s,
its changes of several seeds per side ``satterthwaite``'s): over normal, heavy and ranks at
10-40 trials per class, 1,000 replications, the changes short of 93 % went from 8 cells to 4
(``ranks`` d TN 0.842-0.920 -> 0.904-0.936, d AUROC 0.844-0.904 -> 0.914-0.932; normal d TN at
20 0.919 -> 0.939; heavy d TN at 10 0.915 -> 0.937), those over 97 % from 6 to 7, three of them
up to 0.008 over. Where the study's heavy-tailed scenario stays short (the AUROC at 10 trials
per class, the TN rate at 10-20), no interval built from the sample can reach 93 %: a test set
holding no failing trial is distributed exactly as the normal scenario's, and
``benchmarks/bench_coverage_limit.py`` measures how far that caps the coverage.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import beta as beta_dist
from scipy.stats import t as student_t

from slipbench.seeding import rng_for

LEVEL = 0.95
N_RESAMPLES = 999
METHODS = (
    "satterthwaite",
    "t",
    "percentile",
    "studentized",
    "mover",
    "replicate-logit",
    "scale-choice",
)
#: the interval every figure and change takes unless told otherwise (``docs/coverage.md``)
DEFAULT_METHOD = "scale-choice"
#: a method that differs from another only in its changes: the method whose figures it takes
FIGURES_AS = {"scale-choice": "replicate-logit"}


@dataclass(frozen=True)
class Design:
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
) -> tuple[Design, list[np.ndarray]]:
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
    class. A class of one cluster stays alone: figures that draw on it are not estimable.

    Parameters
    ----------
    y_true, groups : sequence of ndarray of shape (n_windows_i,)
        Per test set: labels (1 slip) and each window's cluster.
    strata : sequence of ndarray of shape (n_windows_i,), optional
        Per test set: each window's balancing stratum.

    Returns
    -------
    design : Design
    codes : list of ndarray of shape (n_windows_i,)
        Per test set, each window's cluster index into the design.
    """
    if len(y_true) != len(groups) or (strata is not None and len(strata) != len(groups)):
        raise ValueError("y_true, groups and strata must hold one array per test set")
    labels, codes_all = np.unique(
        np.concatenate([np.asarray(g) for g in groups]), return_inverse=True
    )
    bounds = np.cumsum([0, *(len(g) for g in groups)])
    codes = [codes_all[a:b] for a, b in zip(bounds[:-1], bounds[1:])]
    y = np.concatenate([np.asarray(v, bool) for v in y_true])
    n = len(labels)
    pos = np.bincount(codes_all, weights=y, minlength=n)
    neg = np.bincount(codes_all, weights=~y, minlength=n)
    kind = np.where(neg == 0, "slip", np.where(pos == 0, "non-slip", "mixed")).astype(object)
    if (kind == "mixed").sum() == 1:
        kind[kind == "mixed"] = (
            "slip" if pos[kind == "mixed"][0] >= neg[kind == "mixed"][0] else "non-slip"
        )
    if strata is None:
        sub = np.full(n, "", dtype=object)
    else:
        s_labels, s_codes = np.unique(
            np.concatenate([np.asarray(s, str) for s in strata]), return_inverse=True
        )
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
    return Design(labels, stratum, np.bincount(stratum)), codes


def resample_weights(design: Design, seed: int, n_resamples: int = N_RESAMPLES) -> np.ndarray:
    """Cluster weights of stratified Rao-Wu bootstrap resamples: in a stratum of ``n_h``
    clusters, ``n_h - 1`` drawn with replacement, each weighted ``n_h / (n_h - 1)``; a lone
    cluster keeps weight 1.

    Returns
    -------
    ndarray of shape (n_resamples, n_clusters)
    """
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
    design: Design,
    influence: np.ndarray,
    sizes: np.ndarray,
    used: np.ndarray,
    extra: Sequence[tuple[float, float]] = (),
    unsure: float = 0.0,
) -> float:
    """Effective degrees of freedom of a figure's variance.

    Parameters
    ----------
    influence : ndarray of shape (n_clusters,)
        Derivative of the figure by each cluster's weight (its linearization).
    sizes : ndarray of shape (n_clusters,)
        Windows per cluster that the figure draws on.
    used : ndarray of shape (n_clusters,), bool
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
class Interval:
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


def interval(
    statistic: Callable[[np.ndarray], np.ndarray],
    influence: Callable[[np.ndarray], np.ndarray],
    design: Design,
    used: np.ndarray,
    sizes: np.ndarray,
    seed: int,
    level: float = LEVEL,
    n_resamples: int = N_RESAMPLES,
    method: str = DEFAULT_METHOD,
    bounds: tuple[float, float] = (0.0, 1.0),
) -> Interval:
    """Interval of a figure by the stratified cluster bootstrap.

    Parameters
    ----------
    statistic : callable
        Maps cluster weights of shape (n, n_clusters) to the figure under each row, shape (n,);
        weights of ones give the estimate.
    influence : callable
        Maps weights (n, n_clusters) to the figure's derivative by each weight, same shape.
    used : ndarray of shape (n_clusters,), bool
        The clusters the figure draws on.
    sizes : ndarray of shape (n_clusters,)
        Windows per cluster that the figure draws on.
    method : one of METHODS
        ``scale-choice`` (the default, :data:`DEFAULT_METHOD`): figures as
        ``replicate-logit``; a change of two sides apart, one seed each, takes ``mover``'s
        interval where its replicates say the contrast is steadier on the logit scale than on
        its own (:func:`_logit_is_steadier`); every other change (several seeds per side, or
        given as one side: the seeds' paired differences) ``satterthwaite``'s.
        ``replicate-logit``: ``satterthwaite``, except
        that a figure in (0, 1) takes as its logit standard error the larger of the delta
        method's and the SD of its clusters' replicates' logits (:func:`_logit_bounds`; over
        several seeds, the replicates of the seeds' plain mean). ``satterthwaite``: the module
        docstring's three steps. ``t``: estimate ± t quantile
        (df clusters - strata) × bootstrap standard error; ``percentile``. The last two are
        kept as the references the coverage study compares against. ``studentized``: the
        union of the ``satterthwaite`` interval and a bootstrap-t interval
        (:func:`_studentized_bounds`); a study option, see ``docs/coverage.md``. ``mover``: a
        figure in (0, 1) takes the logit t-interval with the larger of the delta-method and the
        replicates' own logit standard error (:func:`_logit_bounds`); a change candidate - base
        of two seeded sides (:func:`seeded_interval` with signs (-1, 1)) takes MOVER over its
        level and contrast (:func:`_mover_bounds`); anything else (a change given as one side),
        as ``satterthwaite``. Every method but the default is a study option, see
        ``docs/coverage.md``.
    bounds : (low, high)
        The range the figure can take: (0, 1) for figures, (-1, 1) for changes.
    """
    return seeded_interval(
        lambda w: [statistic(w)[:, None]],
        lambda w: [influence(w)[:, None, :]],
        (1.0,),
        design,
        used,
        sizes,
        seed,
        level,
        n_resamples,
        method,
        bounds,
    )


@dataclass(frozen=True)
class SeedPool:
    """The seed variance a protocol's cells share: one seed's figure about its side's mean,
    pooled over every cell side of two seeds or more, weighted by and carrying their degrees of
    freedom (:func:`pool_seed_spreads`). Given to :func:`seeded_interval`, it stands for each
    cell's own seed spread, so a cell's seed term rests on the protocol's degrees of freedom,
    not its own two."""

    variance: float
    df: float


def pool_seed_spreads(spreads: Iterable[tuple[float, int]]) -> SeedPool | None:
    """The pooled seed variance of ``(variance over a side's seeds (ddof 1), seeds)`` pairs,
    one per cell side; sides of one seed and NaN spreads carry nothing. None where none is left.
    """
    kept = [(float(v), n - 1) for v, n in spreads if n >= 2 and np.isfinite(v)]
    df = sum(d for _, d in kept)
    if df == 0:
        return None
    return SeedPool(sum(v * d for v, d in kept) / df, float(df))


@dataclass(frozen=True)
class _Replicates:
    """What the resamples of :func:`seeded_interval` give.

    Attributes
    ----------
    boot : two-level replicates (clusters and each side's seeds drawn).
    cluster : replicates of the seeds' plain means (clusters drawn alone).
    sides : per side, its two-level replicates and the seed-by-cluster variance they hold
        beyond the one count an interval keeps.
    seeded : per side of several seeds: its seed variance of its mean, the seed-by-cluster part
        of it and the seeds' degrees of freedom, each scaled by the side's sign squared.
    """

    boot: np.ndarray
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
    boot, cluster = np.zeros(n_resamples), np.zeros(n_resamples)
    seeded: list[tuple[float, float, float]] = []
    sides: list[tuple[np.ndarray, float]] = []
    for k, (sign, f) in enumerate(zip(signs, figures)):
        v = seed_weights(f.shape[1], seed, k, n_resamples)
        side = (f * v).sum(axis=1) / v.sum(axis=1)
        boot += sign * side
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
    return _Replicates(boot[np.isfinite(boot)], cluster, sides, seeded)


def _seed_variance(
    reps: _Replicates,
    at_one: Sequence[np.ndarray],
    signs: Sequence[float],
    pool: SeedPool | None,
) -> tuple[float, float]:
    """The sides' seed variance of their means net of their seed-by-cluster parts (a seed's own
    error on a cluster shows in the seeds' spread and again in the clusters' replicates of
    their mean; counted once, by the clusters), and ``unsure``: the spreads' uncertainty,
    ``sum v^2 / df`` (Satterthwaite for a difference: the net is as uncertain as the spreads it
    is taken from). With ``pool``, every side's spread is the pool's over its seeds, one
    estimate on the pool's degrees of freedom (a side of one seed included)."""
    part = sum(t for _, t, _ in reps.seeded)
    if pool is None:
        spread = sum(v for v, _, _ in reps.seeded)
        unsure = sum(v**2 / d for v, _, d in reps.seeded)
    else:
        spread = sum(k**2 * pool.variance / len(f) for k, f in zip(signs, at_one))
        unsure = spread**2 / pool.df
    return max(0.0, spread - part), unsure


@dataclass(frozen=True)
class _Fit:
    """One interval's ingredients, for the methods' bounds (:func:`_bounds`)."""

    est: float
    se: float
    df: float
    level: float
    bounds: tuple[float, float]
    signs: tuple[float, ...]
    reps: _Replicates
    seed_windows: float  # one seed's windows: the logits' smoothing
    at_one: Sequence[np.ndarray]
    level_df: Callable[[], float]  # the df of the two sides' mean (MOVER's level)
    seed_var: float  # the net seed variance inside ``se``

    @property
    def unit(self) -> bool:
        return self.bounds == (0.0, 1.0)

    def logit_t(self) -> tuple[float, float]:
        """The t-interval, on the logit scale for a figure in (0, 1)."""
        q = student_t.ppf(1 - (1 - self.level) / 2, self.df)
        est, se = self.est, self.se
        if self.unit and 0 < est < 1:
            z, s = np.log(est / (1 - est)), se / (est * (1 - est))
            return float(1 / (1 + np.exp(-(z - q * s)))), float(1 / (1 + np.exp(-(z + q * s))))
        return est - q * se, est + q * se

    def plain_t(self) -> tuple[float, float]:
        q = student_t.ppf(1 - (1 - self.level) / 2, self.df)
        return self.est - q * self.se, self.est + q * self.se


def _no_spread(fit: _Fit, n_used: int) -> tuple[float, float]:
    """No spread: a figure takes the Clopper-Pearson interval with the clusters as the sample
    (the worst case); a change stays a point."""
    if not fit.unit:
        return fit.est, fit.est
    alpha, x = 1 - fit.level, fit.est * n_used
    lo = beta_dist.ppf(alpha / 2, x, n_used - x + 1) if x > 0 else 0.0
    hi = beta_dist.ppf(1 - alpha / 2, x + 1, n_used - x) if x < n_used else 1.0
    return float(lo), float(hi)


def _takes_mover(fit: _Fit, method: str) -> bool:
    """A change of two sides apart takes MOVER: always under ``mover``; under ``scale-choice``
    with one seed per side, where the replicates say the contrast is steadier on the logit
    scale (with 3 seeds apart, MOVER over the two-level replicates raised 8 of 20 false alarms
    in compare's null study, the seed terms below 0 of 20)."""
    if fit.bounds != (-1.0, 1.0) or fit.signs != (-1.0, 1.0):
        return False
    if method == "mover":
        return True
    return (
        method == "scale-choice"
        and not fit.reps.seeded
        and fit.seed_var == 0
        and _logit_is_steadier(fit.reps.sides, fit.seed_windows)
    )


def _bounds(fit: _Fit, method: str) -> tuple[float, float]:
    """The interval of ``method`` for a figure or change with spread (``fit.se > 0``)."""
    one_side = fit.unit and fit.signs == (1.0,) and 0 < fit.est < 1
    if method == "percentile":
        q = (1 - fit.level) / 2
        lo, hi = np.quantile(fit.reps.boot, [q, 1 - q])
        return float(lo), float(hi)
    if method == "t":
        return fit.plain_t()
    if method == "mover" and one_side:
        reps, excess = fit.reps.sides[0]
        return _logit_bounds(reps, excess, fit, fit.seed_windows * len(fit.at_one[0]))
    if FIGURES_AS.get(method, method) == "replicate-logit" and one_side:
        # the clusters' replicates of the seeds' plain mean: seed draws left out, so several
        # seeds' logit spread is the test sets' alone and identical seeds give one seed's
        # interval (the smoothing takes one seed's windows)
        return _logit_bounds(fit.reps.cluster, 0.0, fit, fit.seed_windows)
    if _takes_mover(fit, method):
        means = [float(f.mean()) for f in fit.at_one]
        n = fit.seed_windows * len(fit.at_one[0])
        return _mover_bounds(fit.est, means, fit.reps.sides, (fit.df, fit.level_df()), fit.level, n)
    return fit.logit_t()


def seeded_interval(
    per_seed: PerSeed,
    per_seed_influence: PerSeed,
    signs: Sequence[float],
    design: Design,
    used: np.ndarray,
    sizes: np.ndarray,
    seed: int,
    level: float = LEVEL,
    n_resamples: int = N_RESAMPLES,
    method: str = DEFAULT_METHOD,
    bounds: tuple[float, float] = (0.0, 1.0),
    *,
    seed_pool: SeedPool | None = None,
) -> Interval:
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
    per_seed : callable
        Maps cluster weights (n, n_clusters) to a sequence, one per side, of arrays (n, S_k):
        each seed's figure.
    per_seed_influence : callable
        The same for the derivatives by each cluster weight: arrays (n, S_k, n_clusters).
    signs : sequence of float
        Per side, its weight in the figure: ``(1,)`` for a mean, ``(-1, 1)`` for candidate -
        base; any other weight scales that side's figure and its variance components alike.
    seed_pool : SeedPool, optional
        The seed variance the protocol's cells share (:func:`pool_seed_spreads`): it replaces
        the sides' own seed spreads, with its degrees of freedom.

    Degrees of freedom: the strata's components (:func:`satterthwaite_df`) and the sides' net
    seed variance, whose degrees of freedom are those of a difference, ``net^2 / sum_k
    v_k^2 / (S_k - 1)`` (``v_k`` a side's seed variance of its mean), combined by
    Welch-Satterthwaite: three seeds leave at most two degrees of freedom to a seed-dominated
    variance, fewer the more the net subtracts; a pool leaves its own. With one seed per side
    and no pool this is exactly the one-level interval of :func:`interval`.
    """
    if method not in METHODS:
        raise ValueError(f"unknown interval method {method!r}; choose one of: {', '.join(METHODS)}")
    one = np.ones((1, design.n_clusters))
    with np.errstate(invalid="ignore", divide="ignore"):  # a figure the test set lacks is NaN
        at_one = [np.asarray(f)[0] for f in per_seed(one)]
        est = float(sum(k * f.mean() for k, f in zip(signs, at_one)))
    if not np.isfinite(est):
        return Interval(est, np.nan, np.nan, np.nan, np.nan, False)
    if not used.any() or design.lone()[used].any():
        return Interval(est, bounds[0], bounds[1], np.nan, np.nan, False)
    with np.errstate(invalid="ignore", divide="ignore"):
        w = resample_weights(design, seed, n_resamples)
        reps = _replicates(per_seed(w), at_one, signs, seed)
    net, unsure = _seed_variance(reps, at_one, signs, seed_pool)
    # `unsure` stays in the denominator where the net is cut at 0 too: seeds that happen to
    # agree do not earn the clusters' degrees of freedom (docs/coverage.md)
    extra = [(net, np.inf)] if net > 0 else []
    # the clusters' variance of the seeds' plain means plus the seeds' own: the two-level
    # replicates' variance holds the seed-by-cluster term three times (seed spread, clusters,
    # and the clusters' spread of the drawn seeds' mean), which no single subtraction undoes
    cluster = reps.cluster[np.isfinite(reps.cluster)]
    se = float(np.sqrt(np.var(cluster, ddof=1) + net))
    # every method but the two references builds on the logit t
    side_infl = [np.asarray(g)[0].mean(axis=0) for g in per_seed_influence(one)]
    if method in ("t", "percentile"):
        df = float(design.df(used))
    else:
        infl = sum(k * g for k, g in zip(signs, side_infl))
        df = satterthwaite_df(design, np.asarray(infl), sizes, used, extra, unsure)

    def level_df() -> float:  # the two sides' mean, MOVER's level
        mean_infl = np.asarray(sum(side_infl)) / 2
        quarter = [(v / 4, d) for v, d in extra]
        return satterthwaite_df(design, mean_infl, sizes, used, quarter, unsure / 16)

    fit = _Fit(
        est, se, df, level, bounds, tuple(map(float, signs)), reps,
        sizes[used].sum() / len(at_one[0]), at_one, level_df, net,
    )  # fmt: skip
    if se == 0:
        lo, hi = _no_spread(fit, int(used.sum()))
    else:
        lo, hi = _bounds(fit, method)
    lo, hi = float(max(lo, bounds[0])), float(min(hi, bounds[1]))
    if method == "studentized" and se > 0:
        blo, bhi = _studentized_bounds(
            per_seed,
            per_seed_influence,
            signs,
            design,
            used,
            est,
            seed,
            level,
            n_resamples,
            fit.unit,
        )
        # the union: the t-interval where the sample is symmetric, wider only on a side where
        # the resampled pivots say its skew needs it
        lo, hi = min(lo, max(blo, bounds[0])), max(hi, min(bhi, bounds[1]))
    return Interval(est, lo, hi, se, df, True)


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


def _logit_bounds(reps: np.ndarray, excess: float, fit: _Fit, n: float) -> tuple[float, float]:
    """Methods ``mover`` and ``replicate-logit``, a figure in (0, 1): the logit t-interval whose
    standard error is the larger of ``fit``'s (delta method) and :func:`_logit_sd` of ``reps``
    (net of ``excess``). A rate near its bound whose clusters happen to be good shows a small
    spread; its replicates' logits still reach as far as its worst clusters take them."""
    est = fit.est
    reps = reps[np.isfinite(reps)]
    z = float(np.log(est / (1 - est)))
    s = max(fit.se / (est * (1 - est)), _logit_sd(reps, est, n, excess))
    q = student_t.ppf(1 - (1 - fit.level) / 2, fit.df)
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


def _mover_bounds(
    est: float,
    means: Sequence[float],
    sides: Sequence[tuple[np.ndarray, float]],
    dfs: tuple[float, float],
    level: float,
    n: float,
) -> tuple[float, float]:
    """Method ``mover``, a change candidate - base of figures in [0, 1]: MOVER (Zou and Donner,
    Stat. Med. 27, 2008) over the change's two nearly independent parts on the logit scale,
    the contrast ``delta = logit(cand) - logit(base)`` and the level ``lambda`` (their mean):
    the change is ``f(lambda, delta) = expit(lambda + delta / 2) - expit(lambda - delta / 2)``.

    Each part gets a logit t-interval (standard error :func:`_logit_sd` of its replicates; the
    contrast with the change's degrees of freedom ``dfs[0]``, the level with its own ``dfs[1]``),
    mapped to the change's scale with the other part held at its estimate; the two arms on each
    side combine as MOVER does, with the correlation of the parts' replicates. A level near a
    bound shrinks a change and its spread together; the level's interval says how far it may be
    off, and so how much larger the change may be. Combining the two sides' own intervals
    instead (MOVER on base and candidate) overcovers: their replicates correlate near 1."""
    (rb, tb), (rc, tc) = sides
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
    q_dlt, q_lam = (student_t.ppf(1 - alpha / 2, d) for d in dfs)
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


def classic_weights(design: Design, seed: int, n_resamples: int = N_RESAMPLES) -> np.ndarray:
    """Cluster weights of the textbook stratified bootstrap (``n_h`` of ``n_h`` drawn, stream
    ``bootstrap-t``): a resample is a sample of the same size, so its linearized standard error
    (:func:`linearized_variance`) is built like the test set's own, as a studentized pivot needs.

    Returns
    -------
    ndarray of shape (n_resamples, n_clusters)
    """
    rng = rng_for(seed, "bootstrap-t")
    w = np.ones((n_resamples, design.n_clusters))
    for h, n_h in enumerate(design.size):
        if n_h > 1:
            members = np.flatnonzero(design.stratum == h)
            w[:, members] = rng.multinomial(n_h, np.full(n_h, 1 / n_h), size=n_resamples)
    return w


def linearized_variance(
    design: Design, influence: np.ndarray, used: np.ndarray, weights: np.ndarray | None = None
) -> np.ndarray:
    """``sum_h n_h / (n_h - 1) sum_i w_i (r_i - rbar_h)^2`` per row: the linearized variance of
    a figure from its influences ``r`` (n, n_clusters) at cluster weights ``w`` (frequency
    weights summing to ``n_h`` per stratum; ones for the test set itself).

    Returns
    -------
    ndarray of shape (n,)
    """
    w = np.ones_like(influence) if weights is None else weights
    out = np.zeros(influence.shape[0])
    for h, n_h in enumerate(design.size):
        m = (design.stratum == h) & used
        if n_h < 2 or not m.any():
            continue
        r, wm = influence[:, m], w[:, m]
        centre = (wm * r).sum(axis=1, keepdims=True) / wm.sum(axis=1, keepdims=True)
        out += n_h / (n_h - 1) * (wm * (r - centre) ** 2).sum(axis=1)
    return out


def _studentized_bounds(
    per_seed: PerSeed,
    per_seed_influence: PerSeed,
    signs: Sequence[float],
    design: Design,
    used: np.ndarray,
    est: float,
    seed: int,
    level: float,
    n_resamples: int,
    unit: bool,
) -> tuple[float, float]:
    """Bootstrap-t bounds (method ``studentized``): pivots ``(theta* - est) / se*`` over textbook
    cluster resamples (and, per side of several seeds, resampled seeds), ``se*`` the resample's
    linearized standard error plus its seeds' variance of the mean; the test set's own standard
    error is built the same way. Figures in [0, 1] take the pivot on the logit scale. A resample
    with no spread (every drawn cluster alike) has no pivot to speak of: it counts as infinitely
    far on its side, so it widens that side rather than vanishing or dividing by zero."""
    one = np.ones((1, design.n_clusters))
    w = classic_weights(design, seed, n_resamples)
    theta, infl, seed_var = np.zeros(n_resamples), np.zeros_like(w), np.zeros(n_resamples)
    infl_one, seed_var_one = np.zeros_like(one), 0.0
    with np.errstate(invalid="ignore", divide="ignore"):
        sides = zip(
            signs, per_seed(w), per_seed_influence(w), per_seed(one), per_seed_influence(one)
        )
        for k, (sign, f, g, f1, g1) in enumerate(sides):
            n_seeds = f.shape[1]
            v = np.ones((n_resamples, 1))
            if n_seeds > 1:
                rng = rng_for(seed, "bootstrap-t-seeds", k)
                v = rng.multinomial(
                    n_seeds, np.full(n_seeds, 1 / n_seeds), size=n_resamples
                ).astype(float)
                mean = (f * v).sum(axis=1) / n_seeds
                seed_var += (v * (f - mean[:, None]) ** 2).sum(axis=1) / (n_seeds - 1) / n_seeds
                seed_var_one += float(np.asarray(f1)[0].var(ddof=1)) / n_seeds
            theta += sign * (f * v).sum(axis=1) / n_seeds
            infl += sign * (g * v[:, :, None]).sum(axis=1) / n_seeds
            infl_one += sign * np.asarray(g1).mean(axis=1)
        se_star = np.sqrt(linearized_variance(design, infl, used, w) + seed_var)
        se_one = float(np.sqrt(linearized_variance(design, infl_one, used)[0] + seed_var_one))
    ok = np.isfinite(theta) & np.isfinite(se_star)
    theta, se_star = theta[ok], se_star[ok]
    if not ok.any() or not se_one > 0:
        return est, est
    logit = unit and 0 < est < 1
    with np.errstate(invalid="ignore", divide="ignore"):
        if logit:
            th = np.clip(theta, 1e-9, 1 - 1e-9)  # a resample at the bound: far, not infinite
            d = np.log(th / (1 - th)) - np.log(est / (1 - est))
            s, s_one = se_star / (th * (1 - th)), se_one / (est * (1 - est))
        else:
            d, s, s_one = theta - est, se_star, se_one
        pivot = np.where(s > 0, d / np.where(s > 0, s, 1.0), np.sign(d) * 1e12)
    alpha = 1 - level
    q_lo, q_hi = np.quantile(pivot, [alpha / 2, 1 - alpha / 2])
    if logit:
        z = np.log(est / (1 - est))
        q_lo, q_hi = np.clip([q_lo, q_hi], -700 / max(s_one, 1e-300), 700 / max(s_one, 1e-300))
        return float(1 / (1 + np.exp(-(z - q_hi * s_one)))), float(
            1 / (1 + np.exp(-(z - q_lo * s_one)))
        )
    return est - q_hi * s_one, est - q_lo * s_one
