"""Pure functions from (y_true, y_pred or scores, groups) to figures with confidence intervals.

Windows cut from one recording are correlated, so every interval here comes from the
stratified cluster bootstrap of :mod:`slipbench.stats.bootstrap`: whole clusters (``groups``: a
recording, or a trial shared by several units) are resampled within their class, never single
windows. Its coverage is measured, not assumed: see that module's docstring and
``tests/stats/test_coverage.py``. Window-level Wilson intervals are offered beside them for the view
that treats windows as independent; ``tests/stats/test_metrics.py`` shows they undercover. They
are also a floor: clustering widens an interval, never narrows it (:func:`binomial_floor`).

Figures: ``accuracy`` (windows correct), ``tp_rate`` (slip windows caught), ``tn_rate``
(non-slip windows passed), ``balanced_accuracy`` (their mean) and ``auroc``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from functools import partial

import numpy as np
import pandas as pd
import scipy  # scipy.stats loads on first use (see slipbench.stats)

from slipbench.stats.bootstrap import (
    DEFAULT_METHOD,
    LEVEL,
    N_RESAMPLES,
    ClusterDesign,
    Clusters,
    IntervalEstimate,
    IntervalMethod,
    IntervalSpec,
    SeededFigure,
    interval,
    make_design,
    seeded_interval,
)
from slipbench.stats.noise import SeedNoise
from slipbench.store.columns import (
    AUROC,
    BALANCED_ACCURACY,
    EVERY_WINDOW,
    NONSLIP_WINDOWS,
    SLIP_WINDOWS,
    WINDOWED,
    Figure,
    figures,
    names,
)
from slipbench.store.columns import FIGURES as COLUMN_FIGURES
from slipbench.vocabulary import LOW_N

#: a windowed cell's figures, in the results schema's order
FIGURES = names(WINDOWED)
#: the figures that are shares of windows (their class's, or every window)
RATES = tuple(f.name for f in figures(WINDOWED) if f.rate)


def class_masks(y_true: np.ndarray) -> dict[str, np.ndarray]:
    """The windows each rate of :data:`RATES` counts, by the schema's ``rate`` (shape
    (n_windows,) each): every window, the slip windows, the non-slip windows."""
    y = np.asarray(y_true, bool)
    return {EVERY_WINDOW: np.ones(len(y), bool), SLIP_WINDOWS: y, NONSLIP_WINDOWS: ~y}


# ----------------------------------------------------------------------------- low n
def cluster_counts(y_true: np.ndarray, groups: np.ndarray) -> tuple[int, int]:
    """Clusters holding slip windows and clusters holding non-slip windows.

    Parameters
    ----------
    y_true, groups : ndarray of shape (n_windows,)

    Returns
    -------
    (n_slip, n_nonslip); a cluster holding both classes counts in both.
    """
    y_true = np.asarray(y_true, bool)
    groups = np.asarray(groups)
    return len(pd.unique(groups[y_true])), len(pd.unique(groups[~y_true]))


def classes_low_n(n_slip: int, n_nonslip: int) -> bool:
    """True when a class the test set holds has fewer than ``LOW_N`` clusters (trials).

    A class the test set does not hold at all (a one-class test set, tested with a model
    trained elsewhere) is no small sample: its figure (TN or TP rate) is absent, not uncertain,
    so a one-class test set of many trials is not flagged; an empty one is.
    """
    return bool(classes_low_n_of(np.array([n_slip]), np.array([n_nonslip]))[0])


def classes_low_n_of(n_slip: np.ndarray, n_nonslip: np.ndarray) -> np.ndarray:
    """:func:`classes_low_n` of each pair of counts, at once: (n,) bool."""
    slip, nonslip = np.asarray(n_slip, float), np.asarray(n_nonslip, float)

    def few(n: np.ndarray) -> np.ndarray:
        return (n > 0) & (n < LOW_N)

    return ((slip <= 0) & (nonslip <= 0)) | few(slip) | few(nonslip)


def stream_low_n(n_trials: float, n_onsets: float, n_nonslip_trials: float = np.inf) -> bool:
    """True when a streaming cell rests on few events: fewer than ``LOW_N`` test trials that
    hold its slip onsets (``n_trials``), fewer than ``LOW_N`` onsets, or fewer than ``LOW_N``
    trials with non-slip time behind its false alarms (``n_nonslip_trials``, where known).

    ``n_trials`` must count the trials the intervals resample, those holding a detected or
    missed onset (``n_onset_trials`` of :func:`slipbench.stream.metrics.summarize`), not every
    trial streamed: 3 slip trials of 5 onsets each among 20 trials of pressing give intervals
    over 3 clusters. Rows written before onset trials were counted hold only all their test
    trials, which flags no fewer cells than it should.
    """
    counts = (n_trials, n_onsets, n_nonslip_trials)
    return not all(n >= LOW_N for n in counts)  # NaN counts are low too


# ----------------------------------------------------------------------------- per-cluster totals
@dataclass(frozen=True)
class _Totals:
    """One test set's sufficient statistics per design cluster, each of shape (n_clusters,),
    keyed by the windows a rate counts (:func:`class_masks`); ``pairs`` (slip clusters x
    non-slip clusters) holds correctly ranked window pairs."""

    hits: dict[str, np.ndarray]
    size: dict[str, np.ndarray]
    pos: np.ndarray | None = None  # clusters holding slip windows (indices), for the AUROC
    neg: np.ndarray | None = None
    pairs: np.ndarray | None = None


def _totals(
    y_true: np.ndarray,
    correct: np.ndarray,
    codes: np.ndarray,
    n_clusters: int,
    scores: np.ndarray | None,
) -> _Totals:
    y = np.asarray(y_true, bool)
    hits, size = {}, {}
    for windows, mask in class_masks(y).items():
        hits[windows] = np.bincount(codes[mask], weights=correct[mask], minlength=n_clusters)
        size[windows] = np.bincount(codes[mask], minlength=n_clusters).astype(float)
    if scores is None or y.all() or not y.any():
        return _Totals(hits, size)
    pos, neg = np.flatnonzero(size[SLIP_WINDOWS]), np.flatnonzero(size[NONSLIP_WINDOWS])
    return _Totals(
        hits, size, pos, neg, _pair_counts(y, np.asarray(scores, float), codes, pos, neg)
    )


def _pair_counts(
    y: np.ndarray, scores: np.ndarray, codes: np.ndarray, pos: np.ndarray, neg: np.ndarray
) -> np.ndarray:
    """``A[i, j]``: pairs (slip window of cluster pos[i], non-slip window of cluster neg[j])
    ranked correctly, ties counting one half. Shape (len(pos), len(neg)).

    Two searches of every slip score among all non-slip scores, then per non-slip cluster the
    windows of it below each slip score read from running counts (a block of clusters at a time,
    to bound memory): one search per cluster took a third of a cell's statistics. Every sum is
    of halves, exact in float64, so the order of summing does not matter."""
    s_pos, c_pos = scores[y], np.searchsorted(pos, codes[y])
    order = np.argsort(scores[~y], kind="stable")
    ns, nc = scores[~y][order], np.searchsorted(neg, codes[~y][order])
    left, right = np.searchsorted(ns, s_pos, "left"), np.searchsorted(ns, s_pos, "right")
    by_cluster = np.argsort(c_pos, kind="stable")  # every slip cluster holds a slip window
    starts = np.searchsorted(c_pos[by_cluster], np.arange(len(pos)))
    left, right = left[by_cluster], right[by_cluster]
    out = np.zeros((len(pos), len(neg)))
    block = max(1, _PAIR_BLOCK // (max(len(ns), len(s_pos)) + 1))  # bounds both gathers
    for first in range(0, len(neg), block):
        upto = min(first + block, len(neg))
        member = (nc[:, None] == np.arange(first, upto)[None]).astype(np.int32)
        running = np.concatenate([np.zeros((1, upto - first), np.int32), member.cumsum(axis=0)])
        twice = running[left] + running[right]  # below counted twice, ties once
        out[:, first:upto] = 0.5 * np.add.reduceat(twice, starts, axis=0, dtype=np.int64)
    return out


#: entries of the running counts held at once by :func:`_pair_counts` (about 32 MB of int32)
_PAIR_BLOCK = 8_000_000


def _figure(t: _Totals, name: str, w: np.ndarray) -> np.ndarray:
    """A figure of one test set under cluster weights ``w`` (n, n_clusters): shape (n,). A rate
    is the share of its windows that are correct; any other figure has its own computation
    (:data:`COMPUTED`)."""
    rate = COLUMN_FIGURES[name].rate
    if rate:
        return (w @ t.hits[rate]) / (w @ t.size[rate])
    return COMPUTED[name].value(t, w)


def _influence(t: _Totals, name: str, w: np.ndarray) -> np.ndarray:
    """Derivative of a figure by each cluster's weight at weights ``w`` (n, n_clusters)."""
    rate = COLUMN_FIGURES[name].rate
    if rate:
        return _share_influence(t, rate, w)
    return COMPUTED[name].influence(t, w)


def _balanced(t: _Totals, w: np.ndarray) -> np.ndarray:
    slip, nonslip = ((w @ t.hits[c]) / (w @ t.size[c]) for c in (SLIP_WINDOWS, NONSLIP_WINDOWS))
    return 0.5 * (slip + nonslip)


def _balanced_influence(t: _Totals, w: np.ndarray) -> np.ndarray:
    return 0.5 * (_share_influence(t, SLIP_WINDOWS, w) + _share_influence(t, NONSLIP_WINDOWS, w))


def _auroc(t: _Totals, w: np.ndarray) -> np.ndarray:
    """The AUROC of a cluster resample is a bilinear form in the weights of slip and non-slip
    clusters over the pair counts, ``w_pos @ A @ w_neg / ((w_pos @ n_pos) (w_neg @ n_neg))``:
    milliseconds per cell, where 999 calls of ``sklearn.metrics.roc_auc_score`` take about a
    second on 8 000 windows. The estimate equals ``roc_auc_score`` (tested)."""
    if t.pairs is None:  # without scores or without both classes
        return np.full(len(w), np.nan)
    wp, wn = w[:, t.pos], w[:, t.neg]
    return ((wp @ t.pairs) * wn).sum(axis=1) / (
        (wp @ t.size[SLIP_WINDOWS][t.pos]) * (wn @ t.size[NONSLIP_WINDOWS][t.neg])
    )


def _auroc_influence(t: _Totals, w: np.ndarray) -> np.ndarray:
    out = np.zeros_like(w)
    if t.pairs is None:
        return out * np.nan
    sp, sn = t.size[SLIP_WINDOWS][t.pos], t.size[NONSLIP_WINDOWS][t.neg]
    wp, wn = w[:, t.pos], w[:, t.neg]
    n_pos, n_neg = wp @ sp, wn @ sn
    a = ((wp @ t.pairs) * wn).sum(axis=1) / (n_pos * n_neg)
    out[:, t.pos] += (wn @ t.pairs.T - a[:, None] * sp * n_neg[:, None]) / (n_pos * n_neg)[:, None]
    out[:, t.neg] += (wp @ t.pairs - a[:, None] * sn * n_pos[:, None]) / (n_pos * n_neg)[:, None]
    return out


@dataclass(frozen=True)
class Computation:
    """A windowed figure that is no share of windows: its value on one test set under cluster
    weights ``w`` (n, n_clusters) -> (n,), and its derivative by each cluster's weight -> (n,
    n_clusters), the bootstrap's influence."""

    value: Callable[[_Totals, np.ndarray], np.ndarray]
    influence: Callable[[_Totals, np.ndarray], np.ndarray]


#: each windowed figure without a ``rate`` in the results schema, with its own computation
COMPUTED: dict[str, Computation] = {
    BALANCED_ACCURACY.name: Computation(_balanced, _balanced_influence),
    AUROC.name: Computation(_auroc, _auroc_influence),
}


def uncomputed(declared: Sequence[Figure], computed: Mapping[str, Computation]) -> list[str]:
    """The windowed figures of ``declared`` that nothing here computes: neither a rate (the
    share of its windows) nor an entry of ``computed``."""
    return [
        f.name for f in declared if f.kind == WINDOWED and not f.rate and f.name not in computed
    ]


def check_computed(declared: Sequence[Figure], computed: Mapping[str, Computation]) -> None:
    """Refuse a schema whose windowed figure has no computation of its own, so that a new
    figure is never computed as another one; raised when this module is imported."""
    missing = uncomputed(declared, computed)
    if missing:
        raise NotImplementedError(
            f"slipbench.store.columns declares the windowed figure(s) {', '.join(missing)} "
            "without a computation: give it a rate (the windows it is the share of) or an "
            "entry in slipbench.stats.metrics.COMPUTED"
        )


check_computed(figures(WINDOWED), COMPUTED)


def _share_influence(t: _Totals, windows: str, w: np.ndarray) -> np.ndarray:
    """Derivative of the share of correct ``windows`` by each cluster's weight."""
    denom = w @ t.size[windows]
    r = (w @ t.hits[windows]) / denom
    return (t.hits[windows] - r[:, None] * t.size[windows]) / denom[:, None]


#: a figure of one test set under cluster weights, or its influence (_figure, _influence)
_PerSet = Callable[[_Totals, str, np.ndarray], np.ndarray]


def _pooled(of: _PerSet, totals: Sequence[_Totals], name: str, w: np.ndarray) -> np.ndarray:
    """``of`` averaged over test sets."""
    return np.mean([of(t, name, w) for t in totals], axis=0)


def _each_side(of: _PerSet, sides: Sequence[_Totals], name: str, w: np.ndarray) -> list[np.ndarray]:
    """``of`` of each side as one seed of it, shape (n, 1, ...): the two sides of a change."""
    return [np.expand_dims(of(t, name, w), 1) for t in sides]


def _sizes(t: _Totals, name: str) -> np.ndarray:
    """Windows per cluster that a figure draws on, shape (n_clusters,)."""
    return t.size[COLUMN_FIGURES[name].rate or EVERY_WINDOW]


def _df_weights(totals: Sequence[_Totals], name: str) -> np.ndarray | None:
    """Each cluster's sum of its windows' squared weights in the balanced accuracy, ``1 / (2
    n_class)`` a window, summed over test sets (:class:`~slipbench.stats.bootstrap.Clusters`);
    None for the other figures, whose windows weigh alike."""
    if name != BALANCED_ACCURACY.name:
        return None
    out = np.zeros_like(totals[0].size[SLIP_WINDOWS])
    for t in totals:
        for rate in (SLIP_WINDOWS, NONSLIP_WINDOWS):
            n = t.size[rate].sum()
            out = out + (t.size[rate] / (2 * n) ** 2 if n > 0 else 0.0)
    return out


def _used(t: _Totals, name: str) -> np.ndarray:
    """The clusters a figure draws on."""
    rate = COLUMN_FIGURES[name].rate
    if rate:
        return t.size[rate] > 0
    return (t.size[SLIP_WINDOWS] > 0) | (t.size[NONSLIP_WINDOWS] > 0)


@dataclass(frozen=True)
class Predictions:
    """One test set's windows: labels, hard predictions, clusters, and optionally scores and
    balancing strata, each of shape (n_windows,)."""

    y_true: np.ndarray
    y_pred: np.ndarray
    groups: np.ndarray
    scores: np.ndarray | None = None
    strata: np.ndarray | None = None


@dataclass(frozen=True)
class SeedOptions:
    """What :func:`over_seeds` takes besides its sides and the interval: the ``figures``, whether
    the sides' seeds pair (``paired``) and the protocol's ``seed_pool`` per figure."""

    figures: Sequence[str] = FIGURES
    paired: bool = False
    seed_pool: Mapping[str, SeedNoise] | None = None


@dataclass(frozen=True)
class PairOptions:
    """What :func:`paired_comparison` takes besides its windows and the interval: each side's
    scores (the AUROC's change), the windows' balancing ``strata`` and the ``figures``."""

    base_scores: np.ndarray | None = None
    cand_scores: np.ndarray | None = None
    strata: np.ndarray | None = None
    figures: Sequence[str] = FIGURES


def _class_counts(parts: Sequence[Predictions]) -> dict[str, int | bool]:
    y = np.concatenate([np.asarray(p.y_true, bool) for p in parts])
    n_slip, n_nonslip = cluster_counts(y, np.concatenate([np.asarray(p.groups) for p in parts]))
    return {
        "n_test_clusters_slip": n_slip,
        "n_test_clusters_nonslip": n_nonslip,
        "low_n": classes_low_n(n_slip, n_nonslip),
    }


def _put(out: dict, key: str, iv: IntervalEstimate) -> None:
    """An interval's estimate, bounds and standard error as ``key``, ``key_lo/_hi/_se``."""
    out[key], out[f"{key}_lo"], out[f"{key}_hi"], out[f"{key}_se"] = (
        iv.estimate,
        iv.lo,
        iv.hi,
        iv.se,
    )


def _joint_design(parts: Sequence[Predictions]) -> tuple[ClusterDesign, list[_Totals]]:
    """The joint design of test sets whose clusters may be shared, and each set's totals on it."""
    has_strata = [p.strata is not None for p in parts]
    if any(has_strata) and not all(has_strata):
        raise ValueError("give balancing strata for every test set or for none")
    design, codes = make_design(
        [p.y_true for p in parts],
        [p.groups for p in parts],
        [p.strata for p in parts if p.strata is not None] if all(has_strata) else None,
    )
    totals = []
    for p, c in zip(parts, codes):
        y = np.asarray(p.y_true, bool)
        correct = (y == np.asarray(p.y_pred, bool)).astype(float)
        totals.append(_totals(y, correct, c, design.n_clusters, p.scores))
    return design, totals


def interval_spec(seed: int, options: dict) -> IntervalSpec:
    """The :class:`IntervalSpec` of ``seed`` and the keywords of ``options`` that name one of
    its fields (``level``, ``n_resamples``, ``method``), taken out of ``options``."""
    named = ("level", "n_resamples", "method")
    return IntervalSpec(seed, **{k: options.pop(k) for k in named if k in options})


def _joint_figures(parts: Sequence[Predictions], spec: IntervalSpec) -> dict:
    """Each figure's mean over ``parts`` with an interval from one joint bootstrap."""
    design, totals = _joint_design(parts)
    out: dict = {}
    unestimable, floored = [], []
    estimates, windows = _floor_inputs([totals])
    counts = _class_counts(parts)
    spec = replace(spec, few_trials=bool(counts["low_n"]))
    for name in FIGURES:
        clusters = Clusters(
            design,
            np.logical_or.reduce([_used(t, name) for t in totals]),
            np.sum([_sizes(t, name) for t in totals], axis=0),
            _df_weights(totals, name),
        )
        iv = interval(
            partial(_pooled, _figure, totals, name),
            partial(_pooled, _influence, totals, name),
            clusters,
            spec,
        )
        iv, bound = _floored(iv, binomial_floor(name, estimates, windows, spec.level))
        _put(out, name, iv)
        if name == "accuracy":
            out["df"] = iv.df
        if np.isfinite(iv.estimate) and not iv.estimable:
            unestimable.append(name)
        if bound:
            floored.append(name)
    out["ci_note"] = _ci_note(unestimable, floored)
    return out | counts


# ----------------------------------------------------------------------------- the binomial floor
#: the rate of each class's windows: the figure that counts them
_RATE_OF = {f.rate: f.name for f in figures(WINDOWED) if f.rate}


def binomial_floor(
    name: str, estimates: Mapping[str, float], windows: Mapping[str, float], level: float = LEVEL
) -> tuple[float, float, float] | None:
    """The binomial interval that no interval of figure ``name`` may be narrower than, and its
    standard error: what the figure's windows say if every window were its own trial. Windows
    of one trial are correlated, so clustering widens this interval and never narrows it; a
    bootstrap over few trials can still come out narrower (a class of two trials that both fail
    their one window gives that class's rate no spread at all), and then this one stands.

    A share of windows (accuracy, TP rate, TN rate) takes Wilson's interval of its windows. The
    balanced accuracy takes Wilson's interval on ``n_eff`` windows, where a proportion at its
    value has the binomial variance of the mean of its two rates,
    ``(p1 q1 / n1 + p0 q0 / n0) / 4``, each rate shrunk by one hit and one miss (so a rate of 0
    or 1 still has a variance): ``n_eff = 4 / (1 / n1 + 1 / n0)`` when the rates agree.

    Parameters
    ----------
    estimates : mapping of figure name to its estimate (the rates of :data:`RATES`).
    windows : mapping of :func:`class_masks`' keys to one test set's (one seed's) windows.

    Returns
    -------
    (lo, hi, se), ``se`` by :func:`_floor_se`; None for a figure without a floor (the AUROC)
    or without windows.
    """
    rate = COLUMN_FIGURES[name].rate
    if rate:
        p, n = estimates[name], windows[rate]
        if not (n > 0 and np.isfinite(p)):
            return None
        lo, hi = wilson_ci(p * n, n, level)
        return lo, hi, _floor_se(lo, hi, level)
    if name != BALANCED_ACCURACY.name:
        return None
    ps = np.array([estimates[_RATE_OF[k]] for k in (SLIP_WINDOWS, NONSLIP_WINDOWS)])
    ns = np.array([windows[k] for k in (SLIP_WINDOWS, NONSLIP_WINDOWS)])
    if not ((ns > 0).all() and np.isfinite(ps).all()):
        return None
    shrunk = (ps * ns + 1) / (ns + 2)
    ba, ba_shrunk = float(ps.mean()), float(shrunk.mean())
    n_eff = ba_shrunk * (1 - ba_shrunk) / float((shrunk * (1 - shrunk) / ns).sum() / 4)
    lo, hi = wilson_ci(ba * n_eff, n_eff, level)
    return lo, hi, _floor_se(lo, hi, level)


def _floor_se(lo: float, hi: float, level: float) -> float:
    """The standard error of a floor: its interval's half-width over the normal quantile, so a
    rate of 0 or 1 keeps the uncertainty its windows leave (``p q / n`` would call it exact)."""
    return float((hi - lo) / 2 / scipy.stats.norm.ppf(0.5 + level / 2))


def _floor_inputs(
    seeds: Sequence[Sequence[_Totals]],
) -> tuple[dict[str, float], dict[str, float]]:
    """The rates' estimates (mean over seeds of the mean over a seed's test sets) and one
    seed's windows of each class (the mean over seeds), from each seed's test sets' totals."""
    with np.errstate(invalid="ignore", divide="ignore"):
        estimates = {
            name: float(
                np.mean(
                    [
                        np.mean([t.hits[rate].sum() / t.size[rate].sum() for t in sets])
                        for sets in seeds
                    ]
                )
            )
            for rate, name in _RATE_OF.items()
        }
    windows = {
        rate: float(np.mean([sum(t.size[rate].sum() for t in sets) for sets in seeds]))
        for rate in _RATE_OF
    }
    return estimates, windows


def _floored(
    iv: IntervalEstimate, floor: tuple[float, float, float] | None
) -> tuple[IntervalEstimate, bool]:
    """``iv`` widened to hold its binomial floor (:func:`binomial_floor`), its standard error
    at least the floor's; and whether the floor widened it. An interval that is not estimable
    (the figure's whole range) is left as it is."""
    if floor is None or not iv.estimable or not (np.isfinite(iv.lo) and np.isfinite(iv.hi)):
        return iv, False
    lo, hi, se = floor
    bound = bool(lo < iv.lo - 1e-12 or hi > iv.hi + 1e-12)
    wider = IntervalEstimate(
        iv.estimate, min(iv.lo, lo), max(iv.hi, hi), max(iv.se, se), iv.df, iv.estimable
    )
    return wider, bound


def _ci_note(unestimable: Sequence[str], floored: Sequence[str]) -> str:
    """Why intervals are wide: a class of a single cluster (the whole range), or the binomial
    floor (:func:`binomial_floor`) reaching past the trials' spread."""
    notes = []
    if unestimable:
        notes.append(
            f"{', '.join(unestimable)}: a class holds a single cluster, so nothing measures how "
            "its clusters vary; the interval given is the figure's whole range"
        )
    if floored:
        notes.append(
            f"{', '.join(floored)}: widened to the binomial (Wilson) interval of its windows, "
            "which its trials' spread fell short of"
        )
    return "; ".join(notes)


# ----------------------------------------------------------------------------- one cell
def classification_figures(
    y_true: np.ndarray, y_pred: np.ndarray, groups: np.ndarray, seed: int, **options
) -> dict[str, float | int | bool | str]:
    """Every figure of one cell, each with an interval from the stratified cluster bootstrap.

    Parameters
    ----------
    y_true, y_pred : ndarray of shape (n_windows,)
        Labels (1 slip) and hard predictions.
    groups : ndarray of shape (n_windows,)
        The cluster of each window: its recording, or its trial where units share trials.
    seed : int
        Seeds every bootstrap, so figures are reproducible.
    scores : ndarray of shape (n_windows,), optional
        Slip probabilities; gives the AUROC.
    strata : ndarray of shape (n_windows,), optional
        Balancing stratum of each window (``Windows.strata()``): clusters are resampled within
        class and stratum.
    level, n_resamples, method
        Interval level, bootstrap resamples, interval method
        (:class:`~slipbench.stats.bootstrap.IntervalSpec`).

    Returns
    -------
    dict
        Counts ``tp, tn, fp, fn``; each figure of ``FIGURES`` with ``_lo``/``_hi`` (interval) and
        ``_se`` (bootstrap standard error); ``df``: the accuracy interval's degrees of freedom;
        window-level Wilson bounds ``<rate>_wilson_lo``/``_hi`` for accuracy, TP and TN rate;
        ``n_test_clusters_slip``, ``n_test_clusters_nonslip`` (clusters holding windows of each
        class) and ``low_n`` (fewer than ``LOW_N`` of a class it holds); ``ci_note``: empty, or which
        intervals are the figure's whole range because a class holds one cluster, and which the
        binomial floor widened (:func:`binomial_floor`). A figure
        without an estimate (no slip window for a TP rate; no scores for the AUROC) is NaN with
        NaN bounds.
    """
    spec = interval_spec(seed, options)
    y_true = np.asarray(y_true).astype(bool)
    y_pred = np.asarray(y_pred).astype(bool)
    out: dict = {
        "tp": int((y_true & y_pred).sum()),
        "tn": int((~y_true & ~y_pred).sum()),
        "fp": int((~y_true & y_pred).sum()),
        "fn": int((y_true & ~y_pred).sum()),
    }
    out |= _joint_figures([Predictions(y_true, y_pred, np.asarray(groups), **options)], spec)
    correct = y_true == y_pred
    masks = class_masks(y_true)
    for f in figures(WINDOWED):
        if f.wilson:
            mask = masks[f.rate]
            out[f"{f.name}_wilson_lo"], out[f"{f.name}_wilson_hi"] = wilson_ci(
                int(correct[mask].sum()), int(mask.sum())
            )
    return out


def wilson_ci(hits: float, n: float, level: float = LEVEL) -> tuple[float, float]:
    """Window-level Wilson interval (statsmodels): right only if windows were independent."""
    if n == 0:
        return float("nan"), float("nan")
    from statsmodels.stats.proportion import proportion_confint

    lo, hi = proportion_confint(hits, n, alpha=1 - level, method="wilson")
    return float(lo), float(hi)


def chance_interval(
    y_true: np.ndarray, y_pred: np.ndarray, level: float = LEVEL
) -> dict[str, float | bool]:
    """Whether hard predictions can be told from chance: the balanced accuracy and its Wilson
    interval, used on a detector's own training windows to say it did not learn.

    Balanced accuracy BA = (TP rate + TN rate) / 2. Its interval is Wilson's score interval of a
    proportion BA observed on n_eff = 4 / (1 / n_slip + 1 / n_nonslip) windows: the size at
    which a proportion has BA's variance under chance (both rates 0.5), so n_eff is the number
    of windows when the classes are balanced and BA is then the accuracy. Windows count as
    independent (as in :func:`wilson_ci`), which narrows the interval: a warning it gives is
    not a false alarm of the width.

    Returns
    -------
    dict: ``balanced_accuracy``, ``lo``, ``hi`` (NaN without both classes), ``n_eff`` and
    ``chance``: True where ``lo`` <= 0.5, the interval holding 0.5 (or lying below it: worse than
    chance); False without both classes.
    """
    y_true = np.asarray(y_true).astype(bool)
    y_pred = np.asarray(y_pred).astype(bool)
    n_slip, n_nonslip = int(y_true.sum()), int((~y_true).sum())
    if not n_slip or not n_nonslip:
        nan = float("nan")
        return {BALANCED_ACCURACY.name: nan, "lo": nan, "hi": nan, "n_eff": 0.0, "chance": False}
    ba = ((y_pred & y_true).sum() / n_slip + (~y_pred & ~y_true).sum() / n_nonslip) / 2
    n = 4 / (1 / n_slip + 1 / n_nonslip)
    lo, hi = wilson_ci(ba * n, n, level)  # a real count: statsmodels takes one
    return {BALANCED_ACCURACY.name: float(ba), "lo": lo, "hi": hi, "n_eff": n, "chance": lo <= 0.5}


# ----------------------------------------------------------------------------- several test sets
def mean_over_test_sets(
    parts: Sequence[Predictions],
    seed: int,
    level: float = LEVEL,
    n_resamples: int = N_RESAMPLES,
    method: str | IntervalMethod = DEFAULT_METHOD,
) -> dict[str, float | int | bool | str]:
    """The mean of each figure over several test sets, with ONE joint bootstrap.

    The fingers of one sensor are recorded in the same trials, so their test sets share
    clusters: pass the trial as ``groups`` and every resample draws a trial for all fingers at
    once. Combining the fingers' half-widths as if they were independent understates the
    interval when their errors move together (same trials, same contact).

    Parameters
    ----------
    parts : sequence of Predictions
        The test sets; a group value shared by two sets is one cluster.

    Returns
    -------
    dict
        Each figure of ``FIGURES`` (the mean over test sets of the per-set figure) with
        ``_lo``/``_hi``/``_se``; ``n_test_sets``; ``n_test_clusters_slip``/``_nonslip`` (over
        the union of the sets), ``low_n`` and ``ci_note`` as in :func:`classification_figures`.
        A figure that one set lacks (no slip window there) is NaN.
    """
    if not parts:
        raise ValueError("mean_over_test_sets needs at least one test set")
    spec = IntervalSpec(seed, level, n_resamples, method)
    return {"n_test_sets": len(parts)} | _joint_figures(parts, spec)


def pool_seeds(
    parts: Sequence[Predictions | Sequence[Predictions]],
    seed: int,
    level: float = LEVEL,
    n_resamples: int = N_RESAMPLES,
    method: str | IntervalMethod = DEFAULT_METHOD,
) -> dict[str, float | int | bool | str]:
    """One cell run under several seeds (``--repeats``): one figure and one interval.

    The seeds' test sets differ (each seed balances and splits anew) but draw on the same
    recordings, and each seed trains anew: the interval is :func:`over_seeds`' two-level
    bootstrap (recordings drawn once for all seeds, seeds drawn too), so both test-set and
    retraining noise are inside it. ``parts`` holds one entry per seed, with recording or trial
    ids as ``groups``: a Predictions, or several (the fingers of one sensor under that seed),
    whose figures are averaged within the seed. Returns what :func:`over_seeds` returns without
    a candidate.
    """
    return over_seeds(parts, None, seed, level=level, n_resamples=n_resamples, method=method)


def seeds_from_rows(
    values: np.ndarray,
    ses: np.ndarray,
    level: float = LEVEL,
    bounds: tuple[float, float] = (-np.inf, np.inf),
) -> tuple[float, float, float]:
    """The mean over seeds of one cell's figure and its interval from the seeds' rows alone, for
    cells whose predictions are not at hand (:func:`pool_seeds` needs them).

    Two parts: the seeds' mean standard error (their test sets draw on the same recordings,
    so their test noise is taken to move together), at the normal quantile; and the spread of
    the seeds' figures over the number of seeds (retraining noise; it holds the part of the test
    noise that differs between seeds once more), at the t quantile of ``S - 1`` degrees of
    freedom. They combine as Banerjee's interval, ``sqrt(z^2 se^2 + t^2 var / S)``, which does
    not run liberal when the spread has two degrees of freedom, as a Welch-Satterthwaite t of the
    sum did: measured coverage of one cell's accuracy with 3 seeds
    (``benchmarks/bench_findings_contrast.py``, scenarios ``seeds-3`` and ``strong-3``, 10-20
    trials per class, 500 replications each; ``docs/studies/coverage.md``) 0.922-0.968, where
    Welch-Satterthwaite gave 0.872-0.932. Clipped to ``bounds``.

    Parameters
    ----------
    values, ses : ndarray of shape (n_seeds,)
        Each seed's figure and its standard error (NaN where unknown: the interval is then NaN).

    Returns
    -------
    (mean, lo, hi)
    """
    values, ses = np.asarray(values, float), np.asarray(ses, float)
    mean = float(values.mean()) if len(values) else np.nan
    if len(values) < 2 or not (np.isfinite(values).all() and np.isfinite(ses).all()):
        return mean, np.nan, np.nan
    test, spread = float(ses.mean()) ** 2, float(values.var(ddof=1)) / len(values)
    z, t = (scipy.stats.t.ppf(0.5 + level / 2, df) for df in (np.inf, len(values) - 1))
    half = float(np.sqrt(z**2 * test + t**2 * spread))
    return mean, max(mean - half, bounds[0]), min(mean + half, bounds[1])


def over_seeds(
    base: Sequence[Predictions | Sequence[Predictions]],
    cand: Sequence[Predictions | Sequence[Predictions]] | None = None,
    seed: int = 0,
    **options,
) -> dict:
    """A cell run under several seeds per side: the seed-averaged figure (``cand`` None) or its
    change, mean(cand) - mean(base), with a two-level bootstrap over trials and seeds.

    Clusters (``groups``: trial or recording ids) are shared across every part of both sides:
    each resample draws clusters once for all of them (stratified by class, Rao-Wu) and, per
    side, draws its seeds (Rao-Wu), then takes the seed-weighted mean of the per-seed figures
    (:func:`slipbench.stats.bootstrap.seeded_interval`). The two sides' windows need not
    coincide. With one seed per side the result equals :func:`mean_over_test_sets` (``cand``
    None) or :func:`paired_comparison` on the same windows.

    Parameters
    ----------
    base, cand : sequence of Predictions, or of sequences of Predictions
        One entry per seed of each side: that seed's test set, or its test sets (the fingers of
        a sensor), whose figures the seed's figure averages.
    figures : sequence of str
        The figures to give (``accuracy`` always comes first: it gives ``df``).
    paired : bool
        The two sides ran the same seeds, in the same order (seed ``k`` of each side shares its
        split): the change is bootstrapped as the seeds' paired differences, one side of
        ``S`` seeds, so the luck a seed gives both sides cancels and the seed variance rests on
        ``S - 1`` degrees of freedom. Without it, each side's seeds are drawn on their own.
    seed_pool : mapping of figure to SeedNoise, optional
        The seed variance of each figure pooled over the protocol's cells
        (:func:`slipbench.stats.pooled.protocol_seed_pool`, built with the same ``paired``): it
        stands for this cell's own seed spread, on the protocol's degrees of freedom, where the
        cell's own is not larger.

    Returns
    -------
    dict
        Without ``cand``: each figure with ``_lo``/``_hi``/``_se``, ``df``, ``ci_note``,
        ``n_test_sets``; with ``cand``: ``d_<figure>`` with ``_lo``/``_hi``/``_se``, ``df`` and
        ``estimable`` (of the accuracy). Both: ``n_test_clusters_slip``/``_nonslip`` (over the
        union of all parts), ``low_n`` (fewer than ``LOW_N`` clusters of a class),
        ``n_seeds_base`` and ``n_seeds_cand`` (0 without a candidate).
    """
    spec = interval_spec(seed, options)
    o = SeedOptions(**options)
    figures, paired, seed_pool = o.figures, o.paired, o.seed_pool
    sides, parts, design, per_side = _seed_sides(base, cand, figures)
    flat = [t for side in per_side for sets in side for t in sets]
    if paired and (cand is None or len(sides[0]) != len(sides[1])):
        raise ValueError("paired seeds need a candidate with as many seeds as the base")
    of_seeds = _paired_seeds if paired else _per_seed
    signs = (1.0,) if cand is None or paired else (-1.0, 1.0)
    prefix = "" if cand is None else "d_"
    out: dict = {} if cand is not None else {"n_test_sets": len(parts)}
    unestimable, floored = [], []
    # a figure's floor: one seed's windows (a change has none: its sides' floors do not add)
    estimates, windows = _floor_inputs(per_side[0]) if cand is None else ({}, {})
    counts = _class_counts(parts)
    spec = replace(spec, few_trials=bool(counts["low_n"]))
    for name in ("accuracy", *(f for f in figures if f != "accuracy")):
        figure = SeededFigure(
            partial(of_seeds, _figure, per_side, name),
            partial(of_seeds, _influence, per_side, name),
            signs,
            (0.0, 1.0) if cand is None else (-1.0, 1.0),
        )
        clusters = Clusters(
            design,
            np.logical_or.reduce([_used(t, name) for t in flat]),
            np.sum([_sizes(t, name) for t in flat], axis=0),
            _df_weights(flat, name),
        )
        pool = None if seed_pool is None else seed_pool.get(name)
        iv = seeded_interval(figure, clusters, spec, pool)
        if cand is None:
            iv, bound = _floored(iv, binomial_floor(name, estimates, windows, spec.level))
            floored += [name] if bound else []
        key = f"{prefix}{name}"
        _put(out, key, iv)
        if name == "accuracy":
            out["df"] = iv.df
            if cand is not None:
                out["estimable"] = iv.estimable
        if np.isfinite(iv.estimate) and not iv.estimable:
            unestimable.append(name)
    if cand is None:
        out["ci_note"] = _ci_note(unestimable, floored)
    return (
        out
        | counts
        | {"n_seeds_base": len(sides[0]), "n_seeds_cand": len(sides[1]) if cand is not None else 0}
    )


_Side = Sequence[Predictions | Sequence[Predictions]]


def _seed_sides(
    base: _Side, cand: _Side | None, figures: Sequence[str]
) -> tuple[list, list[Predictions], ClusterDesign, list[list[list[_Totals]]]]:
    """The sides of :func:`over_seeds` as lists (side, seed, test set), their parts, their joint
    design and each seed's totals in the same nesting."""
    sides = [
        [[p] if isinstance(p, Predictions) else list(p) for p in side]
        for side in ([base] if cand is None else [base, cand])
    ]
    if not all(sides) or not all(sets for side in sides for sets in side):
        raise ValueError("over_seeds needs at least one Predictions per side and seed")
    unknown = set(figures) - set(FIGURES)
    if unknown:
        raise ValueError(f"unknown figures {sorted(unknown)}; choose from {', '.join(FIGURES)}")
    parts = [p for side in sides for sets in side for p in sets]
    design, flat = _joint_design(parts)
    it = iter(flat)  # each seed's totals, in the order of its parts
    per_side = [[[next(it) for _ in sets] for sets in side] for side in sides]
    return sides, parts, design, per_side


def seed_spreads(
    base: _Side, cand: _Side | None, figures: Sequence[str] = FIGURES, paired: bool = False
) -> dict[str, list[tuple[float, int]]]:
    """Per figure, each side's variance over its seeds (ddof 1) and its number of seeds, as
    :func:`over_seeds` forms its sides (``paired``: one side of the seeds' differences): what
    :func:`slipbench.stats.noise.pool_seed_spreads` pools over a protocol's cells."""
    _, _, design, per_side = _seed_sides(base, cand, figures)
    of_seeds = _paired_seeds if paired else _per_seed
    one = np.ones((1, design.n_clusters))
    out = {}
    with np.errstate(invalid="ignore", divide="ignore"):
        for name in figures:
            at_one = [np.asarray(f)[0] for f in of_seeds(_figure, per_side, name, one)]
            out[name] = [(float(f.var(ddof=1)) if len(f) > 1 else np.nan, len(f)) for f in at_one]
    return out


def _per_seed(
    of: _PerSet, per_side: Sequence[Sequence[Sequence[_Totals]]], name: str, w: np.ndarray
) -> list[np.ndarray]:
    """``of`` for each seed of each side, averaged over the seed's test sets: per side an array
    (n, S_side, ...)."""
    return [np.stack([_pooled(of, sets, name, w) for sets in side], axis=1) for side in per_side]


def _paired_seeds(
    of: _PerSet, per_side: Sequence[Sequence[Sequence[_Totals]]], name: str, w: np.ndarray
) -> list[np.ndarray]:
    """``of`` of candidate - base seed by seed: one side of the seeds' paired differences."""
    base, cand = _per_seed(of, per_side, name, w)
    return [cand - base]


# ----------------------------------------------------------------------------- paired comparison
def paired_comparison(
    y_true: np.ndarray,
    base_pred: np.ndarray,
    cand_pred: np.ndarray,
    groups: np.ndarray,
    seed: int,
    **options,
) -> dict[str, float | int | bool]:
    """Two detectors' predictions on the same test windows: the change (candidate - base) of
    every figure with a paired interval from the stratified cluster bootstrap.

    Each resample draws clusters once and evaluates both detectors on them, so what the two
    share (hard recordings) cancels. McNemar's test is not offered: it treats windows as
    independent and, under an exact null, rejected in 17-23 % of cells (issue 11).

    Parameters
    ----------
    y_true, base_pred, cand_pred, groups : ndarray of shape (n_windows,)
        Labels, the two hard predictions, and each window's cluster.
    level : float
        Interval level; :func:`slipbench.gate.compare.compare` passes a Bonferroni-adjusted one.
    base_scores, cand_scores : ndarray of shape (n_windows,), optional
        Slip probabilities: give the change in AUROC.
    figures : sequence of str
        The figures to compare (``accuracy`` always comes first: it gives ``df``).

    Returns
    -------
    dict
        ``d_<figure>`` with ``_lo``/``_hi``/``_se`` for each of ``figures`` (NaN where a side
        lacks the figure); ``df`` and ``estimable`` of the accuracy's change (not estimable when
        a class holds one cluster: the interval is then [-1, 1]); ``n_test_clusters_slip``/``_nonslip``.
    """
    spec = interval_spec(seed, options)
    o = PairOptions(**options)
    base_scores, cand_scores, strata, figures = o.base_scores, o.cand_scores, o.strata, o.figures
    y_true = np.asarray(y_true, bool)
    groups = np.asarray(groups)
    design, (codes,) = make_design([y_true], [groups], None if strata is None else [strata])
    sides = [
        _totals(y_true, (np.asarray(p, bool) == y_true).astype(float), codes, design.n_clusters, s)
        for p, s in ((base_pred, base_scores), (cand_pred, cand_scores))
    ]
    out: dict = {}
    unknown = set(figures) - set(FIGURES)
    if unknown:
        raise ValueError(f"unknown figures {sorted(unknown)}; choose from {', '.join(FIGURES)}")
    for name in ("accuracy", *(f for f in figures if f != "accuracy")):
        # the two sides apart (signs -1, +1), one seed each: as over_seeds takes a change
        figure = SeededFigure(
            partial(_each_side, _figure, sides, name),
            partial(_each_side, _influence, sides, name),
            (-1.0, 1.0),
            (-1.0, 1.0),
        )
        # both sides' windows, as there
        clusters = Clusters(
            design, _used(sides[0], name), np.sum([_sizes(t, name) for t in sides], axis=0)
        )
        iv = seeded_interval(figure, clusters, spec)
        _put(out, f"d_{name}", iv)
        if name == "accuracy":
            out["df"], out["estimable"] = iv.df, iv.estimable
    out["n_test_clusters_slip"], out["n_test_clusters_nonslip"] = cluster_counts(y_true, groups)
    return out
