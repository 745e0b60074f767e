"""Statistics: the stratified design, Rao-Wu variance, AUROC against scikit-learn, flags for
designs too small to estimate, joint intervals over test sets and seeds, paired comparison.
Coverage itself is measured in tests/stats/test_coverage.py."""

from __future__ import annotations

import benchmod  # noqa: F401  (puts the studies on the path)
import numpy as np
import pytest
from sklearn.metrics import balanced_accuracy_score, roc_auc_score
from studies.intervals import method as study

from slipbench.stats.bootstrap import make_design, resample_weights
from slipbench.stats.metrics import (
    FIGURES,
    Predictions,
    classes_low_n,
    classification_figures,
    cluster_counts,
    mean_over_test_sets,
    over_seeds,
    paired_comparison,
    pool_seeds,
    wilson_ci,
)
from slipbench.vocabulary import LOW_N


def correlated_test_set(rng, n_recordings: int, trial_sd: float = 1.0, windows=(10, 60)):
    """Slip and non-slip recordings whose windows share a recording effect on their score."""
    sizes = rng.integers(*windows, size=2 * n_recordings)
    groups = np.repeat(np.arange(2 * n_recordings), sizes)
    y = groups < n_recordings
    score = (
        np.where(y, 0.8, -0.8)
        + rng.normal(0, trial_sd, 2 * n_recordings)[groups]
        + rng.normal(0, 1, len(y))
    )
    return y, score > 0, groups, score


def test_wilson_undercovers_correlated_windows_where_the_cluster_interval_does_not():
    """Windows of a recording share its accuracy: the window-level Wilson interval, which treats
    them as independent, is far too narrow (it is right for independent windows)."""
    rng = np.random.default_rng(5)
    cover_cluster = cover_wilson = 0
    for d in range(150):
        p = rng.beta(8, 2, size=40)  # each recording's own accuracy; the mean, 0.8, is the truth
        sizes = rng.integers(10, 31, size=40)
        groups = np.repeat(np.arange(40), sizes)
        correct = rng.random(len(groups)) < p[groups]
        y = groups % 2 == 0  # both classes, same accuracy distribution
        f = classification_figures(y, np.where(correct, y, ~y), groups, seed=d)
        cover_cluster += f["accuracy_lo"] <= 0.8 <= f["accuracy_hi"]
        cover_wilson += f["accuracy_wilson_lo"] <= 0.8 <= f["accuracy_wilson_hi"]
    assert cover_cluster >= 0.90 * 150, cover_cluster
    assert cover_wilson < 0.80 * 150, cover_wilson
    independent = sum(
        lo <= 0.8 <= hi
        for lo, hi in (wilson_ci(int(rng.binomial(500, 0.8)), 500) for _ in range(400))
    )
    assert 0.92 * 400 <= independent <= 0.98 * 400


def test_design_stratifies_by_class_and_collapses_lone_strata():
    y = np.array([1, 1, 1, 1, 0, 0, 0, 0, 0, 1, 0])
    g = np.array(["a", "a", "b", "c", "d", "e", "f", "g", "h", "m", "m"])
    strata = np.array(["s1", "s1", "s1", "s2", "p1", "p1", "p2", "p2", "p3", "s1", "s1"])
    design, (codes,) = make_design([y], [g], [strata])
    stratum = dict(zip(design.labels, design.stratum))
    # the lone mixed cluster m joins the class holding most of its windows (a tie: slip), and
    # slip's lone stratum s2 (cluster c) joins slip's largest stratum
    assert stratum["a"] == stratum["b"] == stratum["c"] == stratum["m"]
    # non-slip: p3 (cluster h) is its class's only lone stratum, so it joins a largest one
    assert stratum["h"] in (stratum["d"], stratum["f"])
    assert stratum["d"] == stratum["e"] != stratum["a"] and stratum["f"] == stratum["g"]
    assert design.size.sum() == 9 and not design.lone().any()
    np.testing.assert_array_equal(design.labels[codes], g)


def test_rao_wu_weights_keep_stratum_totals_and_give_unbiased_variance():
    rng = np.random.default_rng(0)
    y = np.repeat([1, 0], [4, 6])
    design, _ = make_design([y], [np.arange(10)])
    w = resample_weights(design, seed=1, n_resamples=40000)
    slip = design.stratum == design.stratum[0]
    np.testing.assert_allclose(w[:, slip].sum(1), 4)  # every resample keeps 4 slip clusters
    np.testing.assert_allclose(w[:, ~slip].sum(1), 6)
    # the resampled mean of 4 values varies as s^2 / 4 (unbiased); the plain bootstrap gives 3/4 of it
    x = rng.normal(size=4)
    boot = (w[:, slip] @ x) / 4
    assert boot.var() == pytest.approx(x.var(ddof=1) / 4, rel=0.03)


def test_classification_figures_match_scikit_learn_and_are_deterministic():
    rng = np.random.default_rng(2)
    y, pred, groups, score = correlated_test_set(rng, 20)
    score = np.round(score, 1)  # coarse: many ties
    f = classification_figures(y, pred, groups, seed=0, scores=score)
    assert f["tp"] + f["tn"] + f["fp"] + f["fn"] == len(y)
    assert f["accuracy"] == pytest.approx((pred == y).mean())
    assert f["balanced_accuracy"] == pytest.approx(balanced_accuracy_score(y, pred))
    assert f["auroc"] == pytest.approx(roc_auc_score(y, score), abs=1e-12)
    for name in FIGURES:
        assert f[f"{name}_lo"] < f[name] < f[f"{name}_hi"], name
        assert f[f"{name}_se"] > 0, name
    assert (
        f["n_test_clusters_slip"] == f["n_test_clusters_nonslip"] == 20
        and not f["low_n"]
        and f["ci_note"] == ""
    )
    assert f == classification_figures(y, pred, groups, seed=0, scores=score)
    assert np.isnan(classification_figures(y, pred, groups, seed=0)["auroc"])


def test_intervals_lean_away_from_the_bound():
    """Near 100 % the interval reaches further down than up, as a rate's sampling distribution does."""
    rng = np.random.default_rng(4)
    y, _, groups, score = correlated_test_set(rng, 15)
    f = classification_figures(
        y, score > -1.5, groups, seed=0
    )  # a lenient threshold: TP rate near 1
    assert f["tp_rate"] > 0.9
    assert f["tp_rate"] - f["tp_rate_lo"] > f["tp_rate_hi"] - f["tp_rate"] > 0


def test_no_nan_interval_where_the_figure_exists():
    """Three recordings per class (the old bootstrap drew resamples without one class and gave
    NaN balanced accuracy); every recording perfect (no spread to resample)."""
    rng = np.random.default_rng(3)
    y, pred, groups, score = correlated_test_set(rng, 3)
    f = classification_figures(y, pred, groups, seed=0, scores=score)
    for name in FIGURES:
        assert np.isfinite([f[name], f[f"{name}_lo"], f[f"{name}_hi"]]).all(), name
    assert f["low_n"]
    perfect = classification_figures(y, y, groups, seed=0, scores=y.astype(float))
    for name in FIGURES:
        assert perfect[name] == perfect[f"{name}_hi"] == 1.0
        # every recording perfect: Clopper-Pearson with the recordings as the sample (3 per
        # class, 6 in all), not [1, 1]
        n = 3 if name in ("tp_rate", "tn_rate") else 6
        assert perfect[f"{name}_lo"] == pytest.approx(0.025 ** (1 / n)), name


def test_a_class_of_one_recording_is_flagged_not_faked():
    rng = np.random.default_rng(6)
    y, pred, groups, score = correlated_test_set(rng, 8)
    keep = (groups < 8) | (groups == 8)  # every slip recording, one non-slip recording
    f = classification_figures(y[keep], pred[keep], groups[keep], seed=0, scores=score[keep])
    assert f["n_test_clusters_nonslip"] == 1 and f["low_n"]
    assert 0 < f["tp_rate_lo"] < f["tp_rate_hi"] < 1  # the slip side is estimable
    for name in ("accuracy", "tn_rate", "balanced_accuracy", "auroc"):
        assert (f[f"{name}_lo"], f[f"{name}_hi"]) == (0.0, 1.0) and np.isnan(f[f"{name}_se"]), name
        assert name in f["ci_note"]
    assert "tp_rate" not in f["ci_note"]
    assert np.isnan(
        classification_figures(y[groups < 8], pred[groups < 8], groups[groups < 8], seed=0)[
            "tn_rate"
        ]
    )


def test_low_n():
    y = np.repeat([1, 0], 50)
    groups = np.concatenate([np.arange(50) % 12, 100 + np.arange(50) % 9])
    assert cluster_counts(y, groups) == (12, 9)
    assert classes_low_n(*cluster_counts(y, groups)) and LOW_N == 10
    assert not classes_low_n(
        *cluster_counts(y, np.concatenate([np.arange(50) % 12, 100 + np.arange(50) % 10]))
    )
    f = classification_figures(y, y, groups, seed=0)
    assert (f["n_test_clusters_slip"], f["n_test_clusters_nonslip"], f["low_n"]) == (12, 9, True)


def _fingers(rng, n_trials: int, n_fingers: int = 3):
    """Fingers recorded in the same trials: a trial effect shared by every finger's windows."""
    trial = rng.normal(0, 1.2, 2 * n_trials)
    parts = []
    for _ in range(n_fingers):
        sizes = rng.integers(10, 40, 2 * n_trials)
        groups = np.repeat(np.arange(2 * n_trials), sizes)
        y = groups < n_trials
        score = (
            np.where(y, 0.8, -0.8)
            + trial[groups]
            + rng.normal(0, 0.3, 2 * n_trials)[groups]
            + rng.normal(0, 1, len(y))
        )
        parts.append(Predictions(y, score > 0, groups, score))
    return parts


def test_mean_over_fingers_bootstraps_shared_trials_jointly():
    parts = _fingers(np.random.default_rng(7), 30)
    joint = mean_over_test_sets(parts, seed=0)
    single = [
        classification_figures(p.y_true, p.y_pred, p.groups, seed=0, scores=p.scores) for p in parts
    ]
    for name in FIGURES:
        assert joint[name] == pytest.approx(np.mean([s[name] for s in single]))
        # fingers err together on a shared trial: the joint interval is wider than the fingers'
        # half-widths combined as independent (the old report's rule)
        independent = np.sqrt(
            sum(((s[f"{name}_hi"] - s[f"{name}_lo"]) / 2) ** 2 for s in single)
        ) / len(single)
        assert (joint[f"{name}_hi"] - joint[f"{name}_lo"]) / 2 > 1.3 * independent, name
    assert joint["n_test_sets"] == 3 and joint["n_test_clusters_slip"] == 30
    one = mean_over_test_sets(parts[:1], seed=0)
    ref = single[0]
    assert all(one[k] == pytest.approx(ref[k]) for k in ("accuracy", "accuracy_lo", "auroc_hi"))


def test_pooled_seeds_of_the_same_windows_give_the_single_interval():
    """Seeds that drew the very same test set add no information: pooling them must not shrink
    the interval (averaging bounds as independent seeds would claim sqrt(k) more precision)."""
    rng = np.random.default_rng(8)
    y, pred, groups, score = correlated_test_set(rng, 12)
    one = classification_figures(y, pred, groups, seed=0, scores=score)
    pooled = pool_seeds([Predictions(y, pred, groups, score)] * 4, seed=0)
    for name in FIGURES:
        assert (pooled[name], pooled[f"{name}_lo"], pooled[f"{name}_hi"]) == pytest.approx(
            (one[name], one[f"{name}_lo"], one[f"{name}_hi"])
        ), name


def _reseeded(rng, y, groups, score, sd):
    """The same windows scored by a retrained model: a per-seed effect on its performance."""
    s = score + np.where(y, 1, -1) * rng.normal(0, sd) + rng.normal(0, 0.3, len(score))
    return Predictions(y, s > 0, groups, s)


def test_over_seeds_with_one_seed_per_side_is_the_one_level_interval():
    rng = np.random.default_rng(11)
    y, pred, groups, score = correlated_test_set(rng, 12)
    cand = _reseeded(rng, y, groups, score, 0.5)
    base = Predictions(y, pred, groups, score)
    single = over_seeds([base], seed=3)
    ref = mean_over_test_sets([base], seed=3)
    assert {k: single[k] for k in ref} == ref
    assert single["n_seeds_base"] == 1 and single["n_seeds_cand"] == 0
    pair = over_seeds([base], [cand], seed=3)
    ref = paired_comparison(
        y, pred, cand.y_pred, groups, seed=3, base_scores=score, cand_scores=cand.scores
    )
    assert {k: pair[k] for k in ref} == ref
    assert pair["n_seeds_cand"] == 1 and pair["low_n"] is False


def test_over_seeds_puts_retraining_noise_inside_the_interval():
    """Seeds that disagree widen the interval and cost degrees of freedom; the windows of the
    two sides need not coincide (each seed splits anew)."""
    rng = np.random.default_rng(12)
    y, pred, groups, score = correlated_test_set(rng, 15)
    quiet = [_reseeded(rng, y, groups, score, 0.0) for _ in range(3)]
    noisy = [_reseeded(rng, y, groups, score, 1.0) for _ in range(3)]
    a, b = over_seeds(quiet, seed=0), over_seeds(noisy, seed=0)
    assert a["n_seeds_base"] == 3 and a["n_test_sets"] == 3
    for name in FIGURES:
        assert b[f"{name}_se"] > a[f"{name}_se"], name
    assert b["df"] < 0.8 * a["df"]  # the seed component rests on 2 degrees of freedom
    half = over_seeds(noisy, [p for p in quiet], seed=0)  # the same windows here; now cut them
    keep = groups % 2 == 0
    cut = [
        Predictions(p.y_true[keep], p.y_pred[keep], p.groups[keep], p.scores[keep]) for p in quiet
    ]
    other = over_seeds(noisy, cut, seed=0)
    assert other["n_test_clusters_slip"] == half["n_test_clusters_slip"] == 15
    assert other["d_accuracy_lo"] < other["d_accuracy"] < other["d_accuracy_hi"]
    mean = np.mean([(p.y_pred == p.y_true).mean() for p in noisy])
    assert b["accuracy"] == pytest.approx(mean)


def test_paired_seeds_cancel_the_luck_both_sides_share():
    """Seed k of each side shares a strong effect (its split): paired seed by seed, the change
    keeps its estimate and loses that effect from its interval; unequal seed counts cannot pair."""
    rng = np.random.default_rng(21)
    y, pred, groups, score = correlated_test_set(rng, 15)
    sign = np.where(y, 1.0, -1.0)
    luck = [sign * rng.normal(0, 1.0) for _ in range(3)]
    base = [_reseeded(np.random.default_rng(k), y, groups, score + luck[k], 0.1) for k in range(3)]
    cand = [
        _reseeded(np.random.default_rng(10 + k), y, groups, score + luck[k] + 0.3 * sign, 0.1)
        for k in range(3)
    ]
    apart, paired = over_seeds(base, cand, seed=0), over_seeds(base, cand, seed=0, paired=True)
    for name in FIGURES:
        assert paired[f"d_{name}"] == pytest.approx(apart[f"d_{name}"]), name
    width = lambda d: d["d_accuracy_hi"] - d["d_accuracy_lo"]  # noqa: E731
    assert width(paired) < 0.5 * width(apart)
    with pytest.raises(ValueError, match="as many seeds"):
        over_seeds(base, cand[:2], seed=0, paired=True)
    with pytest.raises(ValueError, match="two sides apart"):
        over_seeds(base, cand, seed=0, paired=True, method=study("mover"))


def test_over_seeds_flags_low_n_and_refuses_bad_input():
    rng = np.random.default_rng(13)
    y, pred, groups, score = correlated_test_set(rng, LOW_N - 1)
    parts = [_reseeded(rng, y, groups, score, 0.3) for _ in range(2)]
    assert over_seeds(parts, parts, seed=0)["low_n"] is True
    assert over_seeds(parts, seed=0)["low_n"] is True
    with pytest.raises(ValueError, match="at least one"):
        over_seeds(parts, [], seed=0)
    with pytest.raises(ValueError, match="unknown figures"):
        over_seeds(parts, figures=("f1",))


def test_mixed_strata_inputs_are_refused():
    rng = np.random.default_rng(9)
    y, pred, groups, _ = correlated_test_set(rng, 5)
    with pytest.raises(ValueError, match="strata"):
        mean_over_test_sets(
            [Predictions(y, pred, groups, strata=y.astype(str)), Predictions(y, pred, groups)],
            seed=0,
        )


def test_paired_comparison_of_identical_predictions_is_exactly_no_change():
    rng = np.random.default_rng(3)
    y, pred, groups, score = correlated_test_set(rng, 15)
    out = paired_comparison(y, pred, pred, groups, seed=0, base_scores=score, cand_scores=score)
    for name in FIGURES:
        assert out[f"d_{name}"] == out[f"d_{name}_lo"] == out[f"d_{name}_hi"] == 0.0, name


def test_paired_comparison_finds_a_degraded_detector():
    rng = np.random.default_rng(4)
    y, base, groups, _ = correlated_test_set(rng, 40)
    cand = np.where(rng.random(len(y)) < 0.3, ~base, base)  # flips 30 % of the base's answers
    out = paired_comparison(y, base, cand, groups, seed=0)
    assert out["d_accuracy"] == pytest.approx((cand == y).mean() - (base == y).mean())
    assert out["d_accuracy_lo"] < out["d_accuracy"] < out["d_accuracy_hi"] < 0
    assert np.isnan(out["d_auroc"])  # no scores
    assert set(paired_comparison(y, base, cand, groups, seed=0, figures=("tp_rate",))) >= {
        "d_accuracy",
        "d_tp_rate",
    }
    with pytest.raises(ValueError, match="unknown figures"):
        paired_comparison(y, base, cand, groups, seed=0, figures=("f1",))


def test_chance_interval_is_wilsons_on_the_balanced_accuracy():
    from statsmodels.stats.proportion import proportion_confint

    from slipbench.stats.metrics import chance_interval

    y = np.r_[np.ones(50), np.zeros(50)]
    # balanced classes: the Wilson interval of the accuracy over every window
    pred = np.r_[np.ones(35), np.zeros(15), np.zeros(35), np.ones(15)]
    c = chance_interval(y, pred)
    assert c["balanced_accuracy"] == pytest.approx(0.7) and c["n_eff"] == 100
    assert (c["lo"], c["hi"]) == pytest.approx(proportion_confint(70, 100, method="wilson"))
    assert not c["chance"]
    # a constant answer is chance whatever the class sizes
    for y_ in (y, np.r_[np.ones(10), np.zeros(90)]):
        c = chance_interval(y_, np.ones(len(y_)))
        assert c["balanced_accuracy"] == 0.5 and c["lo"] < 0.5 < c["hi"] and c["chance"]
    # unequal classes: n_eff = 4 / (1/10 + 1/90) = 36; 0.65 on it reaches 0.5 (too few windows)
    y_ = np.r_[np.ones(10), np.zeros(90)]
    c = chance_interval(y_, np.r_[np.ones(8), np.zeros(2), np.ones(45), np.zeros(45)])
    assert c["n_eff"] == pytest.approx(36) and c["balanced_accuracy"] == pytest.approx(0.65)
    assert c["lo"] < 0.5 and c["chance"]
    # worse than chance counts too; one class cannot say
    assert chance_interval(y, 1 - y)["chance"]
    one = chance_interval(np.ones(5), np.ones(5))
    assert np.isnan(one["balanced_accuracy"]) and not one["chance"]


def test_the_did_not_learn_criterion_against_a_null_and_planted_learning():
    """1,000 replications per case, windows independent: a coin-flip model (balanced accuracy
    0.5) is flagged in about 97.5 % of fits (measured 97-98 % at 84 to 1,184 windows); a model at
    0.7 on 84 windows is flagged in about 4 %, at 0.8 never."""
    from slipbench.stats.metrics import chance_interval

    rng = np.random.default_rng(1)

    def flagged(n: int, ba: float) -> float:
        y = np.arange(n) % 2
        hits = [
            chance_interval(y, np.where(y == 1, u < ba, u >= ba))["chance"]
            for u in rng.random((1000, n))
        ]
        return float(np.mean(hits))

    for n in (84, 1184):
        assert 0.96 <= flagged(n, 0.5) <= 0.99
    assert flagged(84, 0.7) <= 0.08
    assert flagged(84, 0.8) == 0.0


def test_seeded_interval_scales_with_its_signs():
    """A side weighted by c has c times the figure and c times the standard error: the
    seed-by-cluster correction scales with c squared, as the variance it corrects does."""
    from slipbench.stats.bootstrap import (
        Clusters,
        IntervalSpec,
        SeededFigure,
        make_design,
        seeded_interval,
    )

    rng = np.random.default_rng(3)
    n_clusters, n_seeds = 24, 3
    y = np.repeat([True, False], n_clusters // 2)
    design, _ = make_design([y], [np.arange(n_clusters)])
    figs = rng.uniform(0.6, 0.9, (n_seeds, n_clusters))  # each seed's figure per cluster

    def per_seed(w):
        return [(w @ figs.T) / w.sum(axis=1, keepdims=True)]

    def influence(w):
        return [
            np.broadcast_to(figs[None] - per_seed(w)[0][..., None], (len(w), n_seeds, n_clusters))
        ]

    used, sizes = np.ones(n_clusters, bool), np.ones(n_clusters)
    clusters, spec = Clusters(design, used, sizes), IntervalSpec(0)
    one = seeded_interval(SeededFigure(per_seed, influence, (1.0,), (-1, 1)), clusters, spec)
    half = seeded_interval(SeededFigure(per_seed, influence, (0.5,), (-1, 1)), clusters, spec)
    assert half.estimate == pytest.approx(one.estimate / 2)
    assert half.se == pytest.approx(one.se / 2, rel=1e-9) and half.se > 0


@pytest.mark.slow
def test_two_level_variance_counts_the_seed_by_cluster_term_once():
    """Crossed seeds and clusters: a change of two sides of three seeds each, every seed with its
    own error on every cluster (SD 1) and a small effect of its own (SD 0.3). The standard
    error's square averages 1.1 times the change's variance over 800 designs; drawing seeds and
    clusters together and subtracting the interaction once (the two-level replicates hold it
    three times) gave 1.42. The rest is the seed variance's positive part."""
    from slipbench.stats.bootstrap import (
        ClusterDesign,
        Clusters,
        IntervalSpec,
        SeededFigure,
        seeded_interval,
    )

    n, n_seeds = 20, 3
    design = ClusterDesign(np.arange(n), np.repeat([0, 1], n // 2), np.array([n // 2, n // 2]))
    used, sizes = np.ones(n, bool), np.ones(n)
    rng = np.random.default_rng(0)
    est, var = [], []
    for r in range(800):
        shared = rng.normal(0, 1.0, n)
        x = [
            rng.normal(0, 0.3, (n_seeds, 1)) + shared + rng.normal(0, 1.0, (n_seeds, n))
            for _side in range(2)
        ]

        def per_seed(w, x=x):
            return [(w @ s.T) / w.sum(axis=1, keepdims=True) for s in x]

        def influence(w, x=x):
            total = w.sum(axis=1)[:, None, None]
            return [(s[None] - f[..., None]) / total for s, f in zip(x, per_seed(w))]

        iv = seeded_interval(
            SeededFigure(per_seed, influence, (-1.0, 1.0), (-np.inf, np.inf)),
            Clusters(design, used, sizes),
            IntervalSpec(r),
        )
        est.append(iv.estimate)
        var.append(iv.se**2)
    ratio = np.mean(var) / np.var(est, ddof=1)
    assert 0.9 < ratio < 1.25, ratio


def test_pair_counts_equal_counting_every_pair_across_blocks(monkeypatch):
    """The running-count pair matrix equals a brute-force count, ties one half, whether the
    non-slip clusters fit one block or take several."""
    from slipbench.stats import metrics

    rng = np.random.default_rng(3)
    codes = rng.integers(0, 12, 400)
    y = rng.random(400) < 0.5
    scores = np.round(rng.random(400), 1)  # many ties
    pos, neg = np.unique(codes[y]), np.unique(codes[~y])
    brute = np.array(
        [
            [
                sum(
                    (a > b) + 0.5 * (a == b)
                    for a in scores[y & (codes == i)]
                    for b in scores[~y & (codes == j)]
                )
                for j in neg
            ]
            for i in pos
        ]
    )
    assert np.array_equal(metrics._pair_counts(y, scores, codes, pos, neg), brute)
    monkeypatch.setattr(metrics, "_PAIR_BLOCK", 500)  # a few clusters per block
    assert np.array_equal(metrics._pair_counts(y, scores, codes, pos, neg), brute)


def test_sorted_codes_are_numpys_unique():
    from slipbench.stats.bootstrap import sorted_codes

    for values in (
        np.array(["t-10", "t-2", "T", "t-2", "é"], dtype=object),
        np.array(["b", "a", "b"]),
        np.array([5, -1, 5, 3]),
    ):
        labels, codes = sorted_codes(values)
        want_labels, want_codes = np.unique(values, return_inverse=True)
        assert labels.tolist() == want_labels.tolist() and codes.tolist() == want_codes.tolist()


def test_resample_weights_are_kept_read_only_and_redrawn_per_seed():
    design, _ = make_design([np.array([0, 1] * 10)], [np.arange(20)])
    w = resample_weights(design, seed=4, n_resamples=50)
    assert resample_weights(design, seed=4, n_resamples=50) is w and not w.flags.writeable
    assert not np.array_equal(resample_weights(design, seed=5, n_resamples=50), w)
