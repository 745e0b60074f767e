"""Coverage of the intervals, measured by simulation.

Each simulated dataset is a test set of ``m`` slip and ``m`` non-slip recordings with
heterogeneous window counts (slip 10-200, non-slip 5-100 windows, uniform) and windows
correlated within a recording: a window's latent score is ``mu_class + u_rec + a_det,rec + e``,
with a per-recording random effect ``u ~ N(0, tau^2)`` (``tau`` 0.5: intra-recording
correlation of hits 0.14-0.18; ``tau`` 1.5: 0.41-0.47), a detector-by-recording effect
``a ~ N(0, 0.5^2)``, and window noise ``e ~ N(0, 1)`` of which half the variance is shared by
two detectors looking at the same window. A window is called slip when its score exceeds 0 (the
candidate detector of the paired study: ``SHIFT``, fewer slip calls). Population TP rate 0.80
and TN rate 0.92. With ``stratified``, each class holds two balancing strata of ``m / 2``
recordings with different rates (TP 0.70 / 0.90, TN 0.96 / 0.88), passed to the intervals.
Every population figure has a closed form (normal integrals), so coverage is counted against
the truth, not against a bigger simulation.

The CI run uses ``N_DATASETS`` (40) datasets per setting, about 30 s on one core;
``SLIPBENCH_COVERAGE_DATASETS=1000 pytest tests/stats/test_coverage.py`` runs the full study, and
``python tests/stats/test_coverage.py [N] [METHOD]`` prints the tables that :mod:`slipbench.stats.bootstrap`
quotes.
"""

from __future__ import annotations

import itertools
import os
import sys

import benchmod  # noqa: F401  (puts the studies on the path)
import numpy as np
import pandas as pd
import pytest
from scipy.stats import norm
from studies.intervals import method as study_method

from slipbench.stats.bootstrap import DEFAULT_METHOD
from slipbench.stats.metrics import FIGURES, classification_figures, paired_comparison

N_DATASETS = int(os.environ.get("SLIPBENCH_COVERAGE_DATASETS", "40"))
FULL = 500  # datasets per setting from which the study is held to the measured band itself
SIZES = (4, 6, 8, 10, 20, 40)
TAUS = (0.5, 1.5)
TAU_DETECTOR = 0.5
SHARED_NOISE = 0.5
RATES = {
    False: ((0.80,), (0.92,)),
    True: ((0.70, 0.90), (0.96, 0.88)),
}  # per stratum: TP rates, TN rates
SLIP_WINDOWS, NONSLIP_WINDOWS = (10, 200), (5, 100)
SHIFT = 0.3  # the candidate's threshold, latent units


def _means(tau: float, stratified: bool) -> tuple[float, np.ndarray, np.ndarray]:
    """Latent standard deviation and the class means of each stratum."""
    sd = float(np.sqrt(1 + tau**2 + TAU_DETECTOR**2))
    tp, tn = RATES[stratified]
    return sd, norm.ppf(tp) * sd, -norm.ppf(tn) * sd


def truth(tau: float, stratified: bool = False) -> dict[str, float]:
    """Population figures of the base detector and the paired changes (candidate - base)."""
    sd, mu1, mu0 = _means(tau, stratified)
    n1, n0 = np.mean(SLIP_WINDOWS), np.mean(NONSLIP_WINDOWS)

    def figures(threshold: float) -> dict[str, float]:
        tp, tn = norm.cdf((mu1 - threshold) / sd).mean(), norm.cdf((threshold - mu0) / sd).mean()
        auroc = np.mean(
            [norm.cdf((a - b) / (np.sqrt(2) * sd)) for a, b in itertools.product(mu1, mu0)]
        )
        return {
            "accuracy": (n1 * tp + n0 * tn) / (n1 + n0),
            "tp_rate": tp,
            "tn_rate": tn,
            "balanced_accuracy": (tp + tn) / 2,
            "auroc": auroc,
        }

    base, cand = figures(0.0), figures(SHIFT)
    return base | {f"d_{k}": cand[k] - base[k] for k in base}


def dataset(
    rng: np.random.Generator, m: int, tau: float, stratified: bool = False
) -> dict[str, np.ndarray]:
    """One simulated test set: labels, recordings, balancing strata, the two detectors' scores."""
    sd, mu1, mu0 = _means(tau, stratified)
    sizes = np.concatenate(
        [
            rng.integers(SLIP_WINDOWS[0], SLIP_WINDOWS[1] + 1, m),
            rng.integers(NONSLIP_WINDOWS[0], NONSLIP_WINDOWS[1] + 1, m),
        ]
    )
    groups = np.repeat(np.arange(2 * m), sizes)
    y = groups < m
    half = (
        (groups % m) >= m // 2 if stratified else np.zeros(len(y), bool)
    )  # second stratum of each class
    mean = np.where(
        y, mu1[half.astype(int) * (len(mu1) - 1)], mu0[half.astype(int) * (len(mu0) - 1)]
    )
    u = rng.normal(0, tau, 2 * m)[groups]
    shared = rng.normal(0, np.sqrt(SHARED_NOISE), len(y))
    scores = [
        mean
        + u
        + rng.normal(0, TAU_DETECTOR, 2 * m)[groups]
        + shared
        + rng.normal(0, np.sqrt(1 - SHARED_NOISE), len(y))
        for _ in range(2)
    ]
    strata = np.char.add(np.where(y, "slip|", "non-slip|"), half.astype(int).astype(str))
    return {"y": y, "groups": groups, "strata": strata, "base": scores[0], "cand": scores[1]}


def study(
    n_datasets: int,
    sizes=SIZES,
    taus=TAUS,
    method: str = DEFAULT_METHOD,
    stratified: bool = False,
    seed: int = 0,
) -> pd.DataFrame:
    """Coverage of every figure's interval and of the paired changes: one row per (m, tau)."""
    rows = []
    for tau in taus:
        true = truth(tau, stratified)
        for m in sizes:
            rng = np.random.default_rng([seed, m, int(tau * 10), stratified])
            hits = dict.fromkeys(true, 0)
            for d in range(n_datasets):
                data = dataset(rng, m, tau, stratified)
                strata = data["strata"] if stratified else None
                f = classification_figures(
                    data["y"],
                    data["base"] > 0,
                    data["groups"],
                    seed=d,
                    scores=data["base"],
                    strata=strata,
                    method=study_method(method),
                )
                p = paired_comparison(
                    data["y"],
                    data["base"] > 0,
                    data["cand"] > SHIFT,
                    data["groups"],
                    seed=d,
                    base_scores=data["base"],
                    cand_scores=data["cand"],
                    strata=strata,
                    method=study_method(method),
                )
                for name, value in true.items():
                    src = p if name.startswith("d_") else f
                    hits[name] += src[f"{name}_lo"] <= value <= src[f"{name}_hi"]
            rows.append({"m": m, "tau": tau, **{k: v / n_datasets for k, v in hits.items()}})
    return pd.DataFrame(rows)


def pooled(table: pd.DataFrame, min_m: int = 10) -> pd.Series:
    """Coverage of each figure over the settings with at least ``min_m`` recordings per class."""
    return table[table["m"] >= min_m].drop(columns=["m", "tau"]).mean()


# The band each figure's coverage, pooled over m >= 10, is held to: the target 93-97 % except
# where slipbench.stats.bootstrap documents a shortfall (the change in TN rate when a few
# recordings carry the failures) or a conservative excess (the change in AUROC).
BANDS = {name: (0.93, 0.97) for name in (*FIGURES, *(f"d_{f}" for f in FIGURES))}
BANDS |= {"d_tn_rate": (0.91, 0.97), "d_auroc": (0.93, 0.995)}
CI_SLACK = 0.03  # two standard errors of a pooled coverage of 240 datasets


def _check(table: pd.DataFrame) -> None:
    cover = pooled(table)
    slack = 0.0 if N_DATASETS >= FULL else CI_SLACK
    outside = {
        k: round(v, 3)
        for k, v in cover.items()
        if not BANDS[k][0] - slack <= v <= BANDS[k][1] + slack
    }
    assert not outside, outside


@pytest.mark.slow
def test_intervals_cover_at_10_or_more_recordings_per_class():
    table = study(N_DATASETS)
    assert list(table.columns) == ["m", "tau", *BANDS]
    _check(table)


@pytest.mark.slow
def test_intervals_cover_with_balancing_strata():
    _check(study(N_DATASETS, sizes=SIZES if N_DATASETS >= FULL else (10, 20), stratified=True))


def test_the_study_tells_a_bad_interval():
    """The percentile interval (what slipbench gave before) fails the same study at 10 per
    class: the study has the power to reject an interval that undercovers."""
    cover = pooled(study(N_DATASETS, sizes=(10,), method="percentile"))
    assert cover[["accuracy", "tp_rate", "tn_rate", "auroc"]].max() < 0.90, cover.round(3).to_dict()


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else N_DATASETS
    method = sys.argv[2] if len(sys.argv) > 2 else DEFAULT_METHOD
    for stratified in (False, True):
        table = study(n, method=method, stratified=stratified)
        print(f"stratified={stratified}, {n} datasets per setting, method {method}")
        print(table.to_markdown(index=False, floatfmt=".3f"))
        print(pooled(table).round(3).to_string(), flush=True)
