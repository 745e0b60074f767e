"""The leaderboard: ranks over complete cells, one family of pairwise tests for the pairs, the
groups and the diagram, mean figures; its report section pinned by a golden file."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from goldens import check_golden
from hypothesis import given, settings
from hypothesis import strategies as st
from rendering import render_report
from resultgen import fake_rows

from slipbench.report.leaderboard import leaderboard_tables
from slipbench.stats.contrast import from_parts, p_beyond
from slipbench.stats.leaderboard import (
    ALL,
    MARGIN,
    cell_table,
    constant_accuracy,
    crossed_interval,
    entrants,
    leaderboard,
    pairwise,
    rank_scope,
)


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
    # one seed per entrant: every pair undecided, never a difference, never "no", no group
    assert not overall.pairs["decided"].any() and not overall.pairs["differ"].any()
    assert set(overall.pairs["state"]) == {"undecided"} and overall.groups == []
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
    assert not scope.pairs["differ"].any()  # one seed each: undecided


def _keyed(protocol: str, detector: str, decimation: str = "plain") -> pd.DataFrame:
    """Rows with model keys and test parts: a full-rate sampling-rate cell tests the model of
    window-size's window 200 on the same windows, so it holds the same figure."""
    rows = fake_rows(protocol, detector)
    if protocol == "sampling-rate":
        rows = rows.assign(decimation=decimation)
        rows["cell"] = rows["cell"] + decimation
    down = rows["downsample"] if "downsample" in rows else pd.Series(1, index=rows.index)
    dec = rows["decimation"].where(down > 1, "plain") if "decimation" in rows else "plain"
    unit = rows["sensor_type"] + "/" + rows["sensor_instance"]
    rows["model_key"] = detector + "|" + unit + "|" + rows["window"].astype(str) + "|"
    rows["model_key"] += down.astype(str) + "|" + pd.Series(dec, index=rows.index).astype(str)
    rows["test_sensors"], rows["test_where"] = unit, "[]"
    return rows


def test_cells_with_one_model_and_test_set_are_one_block():
    parts = []
    for det in ("holweg", "lstm"):
        parts.append(_keyed("window-size", det))
        for dec in ("plain", "lag"):
            parts.append(_keyed("sampling-rate", det, dec))
    rows = pd.concat(parts, ignore_index=True)
    ws = rows[(rows["protocol"] == "window-size") & (rows["window"] == 200)]
    full = rows[(rows["protocol"] == "sampling-rate") & (rows["downsample"] == 1)]
    acc = ws.set_index(["detector", "sensor_type", "sensor_instance"])["accuracy"]
    rows.loc[full.index, "accuracy"] = acc.loc[
        list(zip(full["detector"], full["sensor_type"], full["sensor_instance"]))
    ].to_numpy()  # the same model on the same windows: the same figure
    board = leaderboard(rows)
    overall = board.scope(ALL)
    # 48 + 96 cells; each unit's two full-rate sampling-rate cells are its window-200 cell
    assert (overall.n_cells, overall.n_duplicates) == (128, 16)
    assert (board.scope("sampling-rate").n_cells, board.scope("sampling-rate").n_duplicates) == (
        88,
        8,
    )
    assert board.scope("window-size").n_duplicates == 0
    # ranks and means over blocks are those over each block counted once
    blocks = cell_table(rows.drop(full.index), "accuracy").dropna()
    assert len(blocks) == 128
    ranks = blocks.rank(axis=1, ascending=False).mean()
    pd.testing.assert_series_equal(
        overall.ranks.sort_index(), ranks.sort_index(), check_names=False
    )
    assert board.means.loc["lstm", "accuracy"] == pytest.approx(blocks["lstm"].mean())
    # the pairwise table: one pair, its difference over blocks, its interval around it
    (pair,) = board.pairs.itertuples(index=False)
    d = blocks[pair.a] - blocks[pair.b]
    assert pair.diff == pytest.approx(d.mean()) and pair.lo < d.mean() < pair.hi
    assert not pair.decided and np.isnan(pair.p)  # one seed each: undecided
    text = render_report(rows, "md", leaderboard_only=True)
    assert "144 finished cells were ranked as 128 blocks, 16 duplicates merged" in text
    assert "undecided, without p, where an entrant ran one seed" in text


def test_pairwise_bonferroni_over_the_decided_pairs():
    rng = np.random.default_rng(3)
    shared = rng.normal(0.7, 0.05, (60, 1))  # the block's difficulty
    seeds = {e: shared + rng.normal(0, 0.01, (60, 3)) for e in "abcd"}
    seeds["a"] = seeds["a"] + 0.05  # a is ahead of every other; b, c, d are alike
    seeds["d"] = seeds["d"][:, :1]  # d ran one seed: its pairs are undecided
    blocks = pd.DataFrame({e: v.mean(axis=1) for e, v in seeds.items()})
    pairs = pairwise(blocks, list("abcd"), seeds=seeds)
    assert len(pairs) == 6
    decided = pairs[pairs["decided"]]
    assert set(zip(decided["a"], decided["b"])) == {("a", "b"), ("a", "c"), ("b", "c")}
    undecided = pairs[~pairs["decided"]]
    assert undecided["p"].isna().all() and set(undecided["state"]) == {"undecided"}
    # one level for the three decided pairs, each interval the one its state reads
    level = 1 - 0.05 / 3
    assert (pairs["level"] == level).all()
    for r in decided.itertuples():
        shown = from_parts(r.diff, r.parts, level, MARGIN)
        assert (r.lo, r.hi) == pytest.approx((shown.lo, shown.hi))
        assert r.p == pytest.approx(min(1.0, 3 * p_beyond(r.diff, r.parts, MARGIN)))
        assert (r.p < 0.05) == r.differ == (r.state == "shown")
    assert decided[decided["a"] == "a"]["differ"].all()
    (bc,) = decided[decided["a"] != "a"].itertuples()
    assert bc.state == "contradicted" and -MARGIN <= bc.lo and bc.hi <= MARGIN
    for r in pairs.itertuples():
        d = blocks[r.a] - blocks[r.b]
        assert r.diff == pytest.approx(d.mean()) and r.lo < r.diff < r.hi


def test_groups_pairs_and_diagram_never_disagree():
    """Every scope's groups are runs of its pairwise table: a pair that differs shares no group;
    neighbours in rank that do not differ share one."""
    # b and c close enough, seed by seed, for their interval to lie inside the margin: a group
    rows = seeded_rows({"a": [0.1, 0.09, 0.11], "b": [0.0, 0.002, -0.001], "c": [0.0, 0.001, 0.0]})
    board = leaderboard(rows)
    overall = board.scope(ALL)
    pd.testing.assert_frame_equal(board.pairs, overall.pairs)
    together = {(x, y) for g in overall.groups for x in g for y in g}
    order = list(overall.ranks.index)
    for r in overall.pairs.itertuples():
        assert r.testable and r.decided == (r.state in ("shown", "contradicted"))
        if r.state != "contradicted":  # shown, or undecided: never joined
            assert (r.a, r.b) not in together
        elif abs(order.index(r.a) - order.index(r.b)) == 1:
            assert (r.a, r.b) in together
    assert order[0] == "a" and overall.groups == [order[1:]]
    # one family: one Bonferroni level over the testable pairs of every scope at once, a
    # scope of the same blocks (window-size's, here every cell's) counted once
    every = pd.concat([s.pairs for s in board.scopes], ignore_index=True)
    assert len(board.scopes) == 2 and int(every["testable"].sum()) == 6
    assert (every["level"] == 1 - 0.05 / 3).all()
    assert board.level == every["level"].iloc[0]


@pytest.mark.parametrize(
    "blocks, seeds",
    [(1, 5), (1, 1), (12, 1), (48, 2), (48, 3)],
    ids=["one block, 5 seeds", "one block, one seed", "one seed", "2 seeds", "3 seeds"],
)
def test_no_pair_without_a_full_interval_reads_decided(blocks, seeds):
    """The issue's one-block case on generated rows (DoS at 500 ms: one unit, one window):
    entrants 14 and 22 points apart in every seed are undecided, never "no"; and on any board,
    every "no" has its interval inside the margin, every "yes" beyond it, and a pair without
    every noise its claim needs is undecided."""
    shifts = {"a": 0.22, "b": 0.14, "c": 0.0, "d": 0.001}
    rng = np.random.default_rng(blocks * 10 + seeds)
    rows = seeded_rows({e: list(x + rng.normal(0, 0.005, seeds)) for e, x in shifts.items()})
    rows = rows[rows["cell"].isin(rows["cell"].unique()[:blocks])]
    board = leaderboard(rows)
    pairs = pd.concat([s.pairs for s in board.scopes], ignore_index=True)
    assert len(pairs) == 6 * len(board.scopes)
    for r in pairs.itertuples():
        if r.state == "contradicted":
            assert -board.margin <= r.lo and r.hi <= board.margin
        if r.state == "shown":
            assert r.lo > board.margin or r.hi < -board.margin
        if not r.testable:
            assert r.state == "undecided" and np.isnan(r.p)
        assert r.decided == (r.state != "undecided")
    if blocks == 1 or seeds == 1:
        assert not pairs["testable"].any() and not pairs["decided"].any()
        assert all(s.groups == [] for s in board.scopes)
        text = render_report(rows, "md", leaderboard_only=True)
        table = text[text.index("**Pairwise") :]
        lacks = "one block" if blocks == 1 else "one seed"
        assert f"| undecided ({lacks}" in table and "| no |" not in table and "| yes |" not in table
    else:
        assert pairs["testable"].all()
    # a group joins contradicted pairs only: an undecided pair (c and d, 0.1 points apart on
    # an interval wider than the margin) is never drawn as "not differing"
    for s in board.scopes:
        joined = {(x, y) for g in s.groups for i, x in enumerate(g) for y in g[i + 1 :]}
        state = {(r.a, r.b): r.state for r in s.pairs.itertuples()}
        assert all(state[p] == "contradicted" for p in joined)
    if seeds == 3:  # two seeds leave one degree of freedom: too few to show 8 points at 99.6 %
        shown = pairs[pairs["state"] == "shown"]
        assert {("a", "b"), ("a", "c"), ("b", "c")} <= set(zip(shown["a"], shown["b"]))


# ----------------------------------------------------------------------------- seeds as a factor
def seeded_rows(
    shifts: dict[str, list[float]], seeds: dict[str, tuple] | None = None
) -> pd.DataFrame:
    """Window-size rows of detectors run under several seeds: a cell's figure is its level (the
    same for every detector) plus the detector's shift under that seed, shared by every cell (one
    split and one initialisation per run), plus a little noise of its own."""
    base = fake_rows("window-size", "holweg")
    rng = np.random.default_rng(5)
    parts = []
    for det, shift in shifts.items():
        for s, seed in zip(shift, (seeds or {}).get(det, range(len(shift)))):
            rows = base.assign(detector=det, seed=seed)
            rows["key"] = rows["key"] + f"-{det}-{seed}"
            rows["accuracy"] = base["accuracy"] + s + rng.normal(0, 0.005, len(rows))
            parts.append(rows)
    return pd.concat(parts, ignore_index=True)


def _closed_form(
    sides: list[np.ndarray], signs: tuple[float, ...], level: float = 0.95
) -> tuple[float, float]:
    """Banerjee's interval over blocks and seeds, written out (no missing seeds)."""
    from scipy.stats import t

    q = 0.5 + level / 2
    per_block = sum(k * x.mean(axis=1) for k, x in zip(signs, sides))
    n = len(per_block)
    half2 = t.ppf(q, n - 1) ** 2 * per_block.var(ddof=1) / n
    for x in sides:
        s = x.shape[1]
        half2 += t.ppf(q, s - 1) ** 2 * x.mean(axis=0).var(ddof=1) / s
    return per_block.mean() - np.sqrt(half2), per_block.mean() + np.sqrt(half2)


def _matrix(rows: pd.DataFrame, det: str) -> np.ndarray:
    mine = rows[rows["detector"] == det]
    return mine.pivot_table(index="cell", columns="seed", values="accuracy").to_numpy()


def test_pairwise_with_repeats_counts_the_seeds():
    """Two equal detectors whose seeds move every cell alike: the blocks alone call them
    different, the interval over blocks and seeds does not, and both are what they say."""
    rows = seeded_rows({"a": [0.03, -0.02, 0.01], "b": [-0.01, 0.02, -0.03]})
    board = leaderboard(rows)
    assert board.n_seeds == 3
    (pair,) = board.pairs.itertuples(index=False)
    a, b = _matrix(rows, "a"), _matrix(rows, "b")
    # the same seeds: paired seed by seed; one test (window-size's scope repeats every cell's)
    assert board.level == 0.95
    lo, hi = _closed_form([a - b], (1.0,), board.level)
    assert (pair.lo, pair.hi) == pytest.approx((lo, hi))
    assert pair.diff == pytest.approx((a - b).mean())
    assert pair.lo < 0 < pair.hi and pair.p > 0.05 and not pair.differ
    blocks = cell_table(rows, "accuracy")
    plain = pairwise(blocks, list(board.pairs[["a", "b"]].iloc[0])).iloc[0]
    # blocks alone: narrow enough to call them different, so the pair is left undecided
    assert not plain.decided and not plain.differ and plain.hi - plain.lo < (hi - lo) / 5
    lo_a, hi_a = _closed_form([a], (1.0,))
    assert tuple(board.means.loc["a", ["accuracy_lo", "accuracy_hi"]]) == pytest.approx(
        (lo_a, hi_a)
    )
    text = render_report(rows, "md", leaderboard_only=True)
    assert "95 % interval over blocks and seeds (up to 3 seeds per block)" in text
    assert "paired seed by seed where both ran the same seeds" in text


def test_pairwise_p_value_and_interval_agree():
    rng = np.random.default_rng(2)
    for shift in (0.0, 0.004, 0.01, 0.03):
        d = shift + rng.normal(0, 0.01, (1, 3)) + rng.normal(0, 0.02, (40, 3))
        iv = crossed_interval([d], (1.0,))
        for margin in (0.0, 0.01):
            c = from_parts(iv.estimate, iv.parts, 0.95, margin)
            p = p_beyond(iv.estimate, iv.parts, margin)
            assert (p < 0.05) == (c.state == "shown")
            if 0 < p < 1:
                gap = abs(iv.estimate) - margin
                assert iv.half_width(1 - p) == pytest.approx(gap, rel=1e-6)


def test_figures_over_low_n_blocks_carry_the_mark():
    """The issue's Xela board (3 test trials per block): the leaderboard printed its means, ranks
    and blocks won without the dagger every other table carries."""
    rows = board_rows()
    rows["low_n"] = rows["sensor_type"] == "BioTacSP"
    tables = leaderboard_tables(leaderboard(rows))
    ranks, means, _, pairs = tables
    assert all(c.endswith("†") for line in ranks.cells for c in line)
    assert all(c.endswith("†") for line in means.cells for c in line)
    assert all(line[0].endswith("†") for line in pairs.cells)
    (note,) = [n for n in means.notes if n.startswith("†")]
    assert "fewer than 10 test trials of a class" in note and "lstm 32 of 127" in note
    clean = leaderboard_tables(leaderboard(board_rows()))
    assert not any("†" in c for t in clean for line in t.cells for c in line)


def test_a_board_of_undecided_pairs_draws_no_group_and_decides_none():
    """The issue's two-block board: every pair holds every noise its claim needs (two blocks,
    three seeds each) but its interval straddles the margin; the groups table once said
    "decided 6 of 6" and drew one group "not shown to differ" beside six "undecided" rows. Now
    the count counts the rows that read yes or no, and an undecided pair joins no group, in the
    table and in the diagram."""
    from slipbench.report.plots import critical_difference

    luck = {"a": [0.3, -0.25, 0.1], "b": [-0.2, 0.28, 0.0], "c": [0.05, -0.3, 0.2]}
    luck["d"] = [0.25, 0.1, -0.3]
    rows = seeded_rows(luck)
    rows = rows[rows["cell"].isin(rows["cell"].unique()[:2])]
    board = leaderboard(rows)
    pairs = pd.concat([s.pairs for s in board.scopes], ignore_index=True)
    assert pairs["testable"].all() and set(pairs["state"]) == {"undecided"}
    assert not pairs["decided"].any() and all(s.groups == [] for s in board.scopes)
    text = render_report(rows, "md", leaderboard_only=True)
    groups = text[text.index("**Do the detectors differ?") : text.index("**Pairwise")]
    assert "| 0 of 6 " in groups and "none: no pair decided" in groups and "{" not in groups
    pairs_table = text[text.index("**Pairwise") :]
    assert pairs_table.count("| undecided ") == 6
    fig = critical_difference(board)
    bars = [ln for ax in fig.axes for ln in ax.lines if ln.get_linewidth() == 2.2]
    assert bars == []  # no group bar drawn


def test_accuracy_is_read_beside_the_constant_answer():
    """The issue's imbalanced test sets: 17-33 % slip, detectors at 54-67 % accuracy where
    "never slip" scores about 80 %. The means table shows the constant answer over the same
    blocks and marks each detector that does not beat it; one that does is not marked."""
    parts = []
    for det, acc in (("holweg", 0.60), ("lstm", 0.66), ("bandpass", 0.93)):
        rows = fake_rows("window-size", det).head(12)
        slip = np.tile([10, 17, 33, 20], 3)  # of 100 windows per test set
        rows["accuracy"] = acc + np.linspace(-0.03, 0.03, len(rows))
        rows["test_slip_windows"], rows["test_nonslip_windows"] = slip, 100 - slip
        parts.append(rows)
    rows = pd.concat(parts, ignore_index=True)
    rows.loc[rows.index[:12], ["test_slip_windows", "test_nonslip_windows"]] = np.nan
    tp = rows.loc[rows.index[:12], "accuracy"] * 0  # holweg's counts from its confusion cells
    slip = np.tile([10, 17, 33, 20], 3)
    rows.loc[rows.index[:12], ["tp", "fn", "tn", "fp"]] = np.c_[tp, slip, 100 - slip, tp]
    constant = constant_accuracy(rows)
    assert constant["accuracy"].iloc[:4].tolist() == pytest.approx([0.9, 0.83, 0.67, 0.8])
    assert constant["never"].all()
    board = leaderboard(rows)
    expected = np.mean([0.9, 0.83, 0.67, 0.8])
    assert board.means["constant_answer"].to_numpy() == pytest.approx([expected] * 3)
    ranks, means = leaderboard_tables(board)[:2]
    assert any(n.startswith("‡ lstm, holweg: accuracy not above") for n in ranks.notes)
    at = means.columns.index("Constant answer (%)")
    assert means.columns[at - 1] == "Classification Accuracy (%)"
    shown = dict(zip([r[0] for r in means.rows], means.cells))
    assert all(c[at] == f"{100 * expected:.1f}" for c in shown.values())
    assert shown["holweg"][at - 1].endswith("‡") and shown["lstm"][at - 1].endswith("‡")
    assert not shown["bandpass"][at - 1].endswith("‡")
    notes = " ".join(means.notes)
    assert '"never slip" on 12 of them' in notes and "holweg 60.0 against 80.0" in notes


def test_without_window_counts_the_table_says_so():
    board = leaderboard(board_rows())
    means = leaderboard_tables(board)[1]
    assert "Constant answer (%)" not in means.columns
    assert any("what the constant answer scores" in n for n in means.notes)
