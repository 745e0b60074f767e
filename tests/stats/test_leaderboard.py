"""The leaderboard: ranks over complete cells, Friedman and Wilcoxon-Holm, groups, mean figures;
its report section pinned by a golden file."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from goldens import check_golden
from hypothesis import given, settings
from hypothesis import strategies as st
from resultgen import fake_rows
from scipy.stats import friedmanchisquare
from statsmodels.stats.multitest import multipletests

from slipbench.report.document import render_report
from slipbench.stats.leaderboard import ALL, cell_table, entrants, leaderboard, rank_scope


def board_rows() -> pd.DataFrame:
    """Three detectors on two protocols; bandpass failed one cell; balanced accuracy and AUROC."""
    parts = []
    for det, shift in (("holweg", 0.0), ("lstm", 0.03), ("bandpass", -0.04)):
        for protocol in ("window-size", "material-holdout"):
            rows = fake_rows(protocol, det, shift=shift)
            rows["balanced_accuracy"] = rows["accuracy"] - 0.01
            rows["auroc"] = rows["accuracy"] + 0.05
            rows["n_test_trials"] = 40
            parts.append(rows)
    rows = pd.concat(parts, ignore_index=True)
    failed = rows.index[(rows["detector"] == "bandpass") & (rows["protocol"] == "window-size")][0]
    rows.loc[failed, ["status", "reason", "accuracy"]] = [
        "failed",
        "detector 'bandpass' raised: boom",
        np.nan,
    ]
    return rows


def test_leaderboard_golden():
    check_golden("leaderboard.md", render_report(board_rows(), "md", leaderboard_only=True))


def test_ranks_tests_and_groups_follow_the_scores():
    rows = board_rows()
    board = leaderboard(rows, protocols=["window-size", "material-holdout"])
    overall = board.scope(ALL)
    assert (
        overall.n_excluded == 1 and overall.n_cells == 48 + 80 - 1
    )  # the failed cell is not ranked
    scores = cell_table(rows, "accuracy").dropna()
    assert set(scores.columns) == {"holweg", "lstm", "bandpass"}
    ranks = scores.rank(axis=1, ascending=False).mean()
    pd.testing.assert_series_equal(
        overall.ranks.sort_index(), ranks.sort_index(), check_names=False
    )
    stat, p = friedmanchisquare(*(scores[c] for c in overall.ranks.index))
    assert overall.friedman == pytest.approx((stat, p))
    assert list(overall.pairs["p_holm"]) == pytest.approx(
        list(multipletests(overall.pairs["p"], method="holm")[1])
    )
    for (
        group
    ) in overall.groups:  # no two members of a group differ, and a group is a run in rank order
        order = list(overall.ranks.index)
        assert group == order[order.index(group[0]) : order.index(group[0]) + len(group)]
        differ = overall.pairs[overall.pairs["a"].isin(group) & overall.pairs["b"].isin(group)][
            "differ"
        ]
        assert not differ.any()
    assert board.order[0] == "lstm"  # 3 points ahead on average
    assert board.means.loc["lstm", "accuracy"] == pytest.approx(scores["lstm"].mean())
    lo, hi = board.means.loc["lstm", ["accuracy_lo", "accuracy_hi"]]
    assert lo < scores["lstm"].mean() < hi
    assert [s.name for s in board.scopes] == [ALL, "window-size", "material-holdout"]


def test_seeds_are_averaged_before_ranking_and_parameter_sets_compete_apart():
    a = fake_rows("window-size", "holweg", seeds=(0, 1, 2))
    assert cell_table(a, "accuracy").shape == (48, 1)
    b = fake_rows("window-size", "holweg", shift=0.02).assign(
        detector_params='{"band": [39, 100], "keep": 0.8}'
    )
    rows = pd.concat(
        [a.assign(detector_params='{"band": null, "keep": 0.8}'), b], ignore_index=True
    )
    assert set(entrants(rows)) == {"holweg (band=null)", "holweg (band=[39, 100])"}
    board = leaderboard(rows)
    assert board.scope(ALL).n_cells == 48 and len(board.order) == 2
    assert "One detector" not in render_report(rows, "md", leaderboard_only=True)


def test_degenerate_boards_say_why():
    one = fake_rows("window-size", "holweg")
    text = render_report(one, "md", leaderboard_only=True)
    assert "One detector: nothing to rank it against." in text
    disjoint = pd.concat(
        [fake_rows("window-size", "holweg"), fake_rows("material-holdout", "lstm")],
        ignore_index=True,
    )
    text = render_report(disjoint, "md", leaderboard_only=True)
    assert "No cell was finished by every detector (128 cells): nothing to rank." in text


@pytest.mark.slow
@settings(max_examples=40, deadline=None)
@given(st.integers(2, 6), st.integers(1, 25), st.integers(0, 2**32 - 1))
def test_any_score_matrix_gives_consistent_ranks(k, n, seed):
    rng = np.random.default_rng(seed)
    scores = pd.DataFrame(
        np.round(rng.uniform(0.5, 1.0, (n, k)), 2), columns=[f"d{i}" for i in range(k)]
    )
    scope = rank_scope(scores, ALL)
    assert scope.ranks.sum() == pytest.approx(
        k * (k + 1) / 2
    )  # ranks of each cell sum to 1 + ... + k
    assert list(scope.ranks) == sorted(scope.ranks)
    assert scope.wins.sum() >= n  # every cell has a winner (ties give several)
    assert len(scope.pairs) == k * (k - 1) // 2
    assert (scope.pairs["p_holm"] >= scope.pairs["p"] - 1e-12).all()
    if k < 3 or n < 2:
        assert scope.friedman is None
    else:
        assert 0 <= scope.friedman[1] <= 1
