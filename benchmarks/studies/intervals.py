"""Interval methods that no command runs: the references and candidates the coverage study
(``docs/studies/coverage.md``, ``benchmarks/bench_coverage.py``) measured slipbench's default against.

Each is an :class:`slipbench.stats.bootstrap.IntervalMethod`, given to the product's functions
as ``method=`` (:func:`method` maps a study's name to it; the product's own names pass through):
``t`` and ``percentile`` (the references), ``replicate-logit`` (the default's figure part
alone), ``mover`` (MOVER for every change of two sides), ``studentized`` (bootstrap-t united
with the t-interval) and ``cr2-bm`` (CR2 standard errors with Bell-McCaffrey degrees of freedom,
the few-cluster remedy of ``benchmarks/bench_coverage_small.py``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
import scipy.stats

from slipbench.seeding import rng_for
from slipbench.stats.bootstrap import (
    METHODS,
    N_RESAMPLES,
    ClusterDesign,
    Clusters,
    Fit,
    IntervalMethod,
    bell_mccaffrey_df,
    logit_bounds,
    mover_change_bounds,
    replicate_logit_bounds,
)


@dataclass(frozen=True)
class Study:
    """A study's interval method: its name, its degrees of freedom and its bounds."""

    name: str
    plain_df: bool
    of: Callable[[Fit], tuple[float, float]]

    def bounds(self, fit: Fit) -> tuple[float, float]:
        return self.of(fit)


def _percentile(fit: Fit) -> tuple[float, float]:
    """The two-level replicates' quantiles (clusters and each side's seeds drawn)."""
    boot = sum(k * side for k, (side, _) in zip(fit.signs, fit.reps.sides))
    boot = np.asarray(boot)[np.isfinite(boot)]
    q = (1 - fit.level) / 2
    lo, hi = np.quantile(boot, [q, 1 - q])
    return float(lo), float(hi)


def _t(fit: Fit) -> tuple[float, float]:
    """Estimate +- t quantile (clusters - strata) x bootstrap standard error."""
    return fit.est - _q(fit) * fit.se, fit.est + _q(fit) * fit.se


def _q(fit: Fit) -> float:
    from scipy.stats import t as student_t

    return float(student_t.ppf(1 - (1 - fit.level) / 2, fit.df))


def _replicate_logit(fit: Fit) -> tuple[float, float]:
    """Figures as the default takes them; every change the t-interval."""
    return replicate_logit_bounds(fit) if fit.one_side else fit.logit_t()


def _mover(fit: Fit) -> tuple[float, float]:
    """A figure: the logit t over the two-level replicates; a change of two sides: MOVER."""
    if fit.one_side:
        reps, excess = fit.reps.sides[0]
        return logit_bounds(reps, excess, fit, fit.seed_windows * len(fit.at_one[0]))
    if fit.bounds == (-1.0, 1.0) and fit.signs == (-1.0, 1.0):
        return mover_change_bounds(fit)
    if fit.bounds == (-1.0, 1.0) and len(fit.signs) == 1:
        raise ValueError("method 'mover' needs the two sides apart, not paired seeds")
    return fit.logit_t()


def _studentized(fit: Fit) -> tuple[float, float]:
    """The union: the t-interval where the sample is symmetric, wider only on a side where the
    resampled pivots say its skew needs it."""
    lo, hi = fit.logit_t()
    blo, bhi = studentized_bounds(fit)
    return min(lo, blo), max(hi, bhi)


def cr2_interval(fit: Fit) -> tuple[float, float, float]:
    """A figure's t-interval on ``fit.df`` degrees of freedom with its CR2 standard error (Bell
    and McCaffrey, Survey Methodology 28, 2002; Pustejovsky and Tipton, J. Bus. Econ. Stat. 36,
    2018), on the logit scale for a figure in (0, 1): the study's ``cr2-bm`` (with
    :func:`~slipbench.stats.bootstrap.bell_mccaffrey_df`).

    Within each stratum a share of windows is a regression on the stratum's intercept: a
    cluster's residual total (its influence net of its windows' share of the stratum's) is
    scaled by ``(1 - h_g)^-1/2``, ``h_g = s_g / N_h`` its leverage, so a cluster holding much of
    a stratum does not shrink the variance as the plain sum of squares (and the bootstrap) does.
    Where the influences show no spread, the bootstrap's standard error stands.

    Returns
    -------
    (lo, hi, se)
    """
    p = fit.problem
    one = np.ones((1, p.design.n_clusters))
    infl = np.asarray(
        sum(k * np.asarray(g)[0].mean(axis=0) for k, g in zip(p.signs, p.per_seed_influence(one))),
        float,
    )
    var = 0.0
    for h, n_h in enumerate(p.design.size):
        m = (p.design.stratum == h) & p.used
        if n_h < 2 or m.sum() < 2:
            continue
        r, size = infl[m], p.sizes[m].astype(float)
        e = r - size * r.sum() / size.sum()  # net of the stratum's own rate
        var += float((e**2 / (1 - np.minimum(size / size.sum(), 1 - 1e-9))).sum())
    se = float(np.sqrt(var)) if var > 0 else fit.se
    q = float(scipy.stats.t.ppf(1 - (1 - fit.level) / 2, fit.df))
    est = fit.est
    if fit.unit and 0 < est < 1:
        z, s = np.log(est / (1 - est)), se / (est * (1 - est))
        return float(1 / (1 + np.exp(-(z - q * s)))), float(1 / (1 + np.exp(-(z + q * s)))), se
    return est - q * se, est + q * se, se


def cr2_bm(fit: Fit) -> tuple[float, float, float, float]:
    """The CR2 t-interval (:func:`cr2_interval`) on Bell-McCaffrey's degrees of freedom, at any
    number of trials (the default takes Bell-McCaffrey's degrees of freedom below ``LOW_N``
    trials a class, with the bootstrap's standard error).

    Returns
    -------
    (lo, hi, se, df)
    """
    p = fit.problem
    df = bell_mccaffrey_df(Clusters(p.design, p.used, p.sizes, p.weights))
    lo, hi, se = cr2_interval(replace(fit, df=df))
    return lo, hi, se, df


def _cr2_bm(fit: Fit) -> tuple[float, float]:
    """The CR2 t-interval with Bell-McCaffrey degrees of freedom (:func:`cr2_bm`)."""
    lo, hi, _, _ = cr2_bm(fit)
    return lo, hi


STUDIES = {
    s.name: s
    for s in (
        Study("t", True, _t),
        Study("percentile", True, _percentile),
        Study("replicate-logit", False, _replicate_logit),
        Study("mover", False, _mover),
        Study("studentized", False, _studentized),
        Study("cr2-bm", False, _cr2_bm),
    )
}


def method(name: str) -> str | IntervalMethod:
    """The method of ``name``: the product's own (:data:`METHODS`) as it is, else a study's."""
    if name in METHODS:
        return name
    if name not in STUDIES:
        raise ValueError(
            f"unknown interval method {name!r}; choose one of: {', '.join([*METHODS, *STUDIES])}"
        )
    return STUDIES[name]


def classic_weights(design: ClusterDesign, seed: int, n_resamples: int = N_RESAMPLES) -> np.ndarray:
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
    design: ClusterDesign,
    influence: np.ndarray,
    used: np.ndarray,
    weights: np.ndarray | None = None,
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


def studentized_bounds(fit: Fit) -> tuple[float, float]:
    """Bootstrap-t bounds (method ``studentized``): pivots ``(theta* - est) / se*`` over textbook
    cluster resamples (and, per side of several seeds, resampled seeds), ``se*`` the resample's
    linearized standard error plus its seeds' variance of the mean; the test set's own standard
    error is built the same way. Figures in [0, 1] take the pivot on the logit scale. A resample
    with no spread (every drawn cluster alike) has no pivot to speak of: it counts as infinitely
    far on its side, so it widens that side rather than vanishing or dividing by zero."""
    p = fit.problem
    per_seed, per_seed_influence, signs, design = (
        p.per_seed,
        p.per_seed_influence,
        p.signs,
        p.design,
    )
    used, est, seed, level, n_resamples = p.used, fit.est, p.seed, p.level, p.n_resamples
    unit = fit.unit
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
