"""The family of tests `slipbench compare` runs: seeds as a factor, pooled tests per protocol,
inconclusive and identical cells, and the JSON's schema. Small synthetic result folders with
predictions (tests/resultgen.py:predictions_pair)."""

from __future__ import annotations

import json
from importlib import resources

import numpy as np
import pytest
from resultgen import predictions_pair

from slipbench.errors import EXIT_UNDECIDED
from slipbench.gate.compare import CELL_ALPHA, compare, summary
from slipbench.gate.gate import DEFAULT_TOLERANCE, Gate
from slipbench.report.compare import SCHEMA_VERSION, comment_markdown, to_json
from slipbench.stats.metrics import Predictions, over_seeds, paired_comparison
from slipbench.stats.pooled import POOLED_METHOD, CellSides, pooled_change


def _preds(rng, n=20):
    y = np.repeat(np.arange(2 * n) % 2 == 0, 6)
    g = np.repeat(np.arange(2 * n), 6).astype(str)
    return [Predictions(y, np.where(rng.random(len(y)) < 0.8, y, ~y), g) for _ in range(2)]


def _lucky(rng, p, luck):
    """``p`` with a share ``|luck|`` of its windows turned right (luck > 0) or wrong (< 0)."""
    flip = rng.random(len(p.y_true)) < abs(luck)
    right = np.where(flip, p.y_true if luck > 0 else ~p.y_true, p.y_pred)
    return Predictions(p.y_true, right, p.groups)


def _pooled(cmp, figure="accuracy"):
    (row,) = cmp.pooled[cmp.pooled["figure"] == figure].to_dict("records")
    return row


def test_a_pooled_change_of_one_cell_is_the_cells_change():
    rng = np.random.default_rng(3)
    (b, c), (b2, c2) = _preds(rng), _preds(rng)
    one = pooled_change([CellSides([b], [c])], seed=4, level=0.99)
    ref = paired_comparison(
        b.y_true,
        b.y_pred,
        c.y_pred,
        b.groups,
        4,
        level=0.99,
        method=POOLED_METHOD,
        figures=("accuracy",),
    )
    assert one["d"] == pytest.approx(ref["d_accuracy"])
    assert (one["lo"], one["hi"]) == pytest.approx((ref["d_accuracy_lo"], ref["d_accuracy_hi"]))
    two = pooled_change([CellSides([b, b2], [c, c2])], seed=4, level=0.99)
    ref = over_seeds(
        [b, b2], [c, c2], seed=4, level=0.99, method=POOLED_METHOD, figures=("accuracy",)
    )
    assert two["seeds"] and (two["lo"], two["hi"]) == pytest.approx(
        (ref["d_accuracy_lo"], ref["d_accuracy_hi"])
    )
    # two cells: the mean of their changes
    both = pooled_change([CellSides([b], [c]), CellSides([b2], [c2])], seed=4, level=0.99)
    assert both["d"] == pytest.approx(
        np.mean(
            [
                np.mean(x.y_pred == x.y_true) - np.mean(w.y_pred == w.y_true)
                for w, x in ((b, c), (b2, c2))
            ]
        )
    )


def test_a_drop_spread_over_a_protocol_is_flagged_by_the_pooled_test(tmp_path):
    """Every window of 10 % of the trials flipped in all cells: no cell can tell, the mean can."""
    base, cand = predictions_pair(tmp_path, n_cells=12, trials=40, flip=0.1)
    cmp = compare(base, cand)
    assert (cmp.cells["verdict"] != "regressed").all()  # too small for any one cell
    assert set(cmp.pooled["figure"]) == {"accuracy", "tn_rate", "tp_rate"}
    pooled = _pooled(cmp)
    assert pooled["verdict"] == "regressed" and pooled["change_hi"] < -1
    assert pooled["method"].startswith("joint cluster bootstrap")
    # one seed per side: retraining noise is not in the interval, so noise alone could do it
    assert cmp.state == "undecided" and cmp.exit_code == EXIT_UNDECIDED == 6
    text = comment_markdown(cmp)
    assert "**Undecided** (exit 6): window-size, holweg: accuracy" in text
    assert "(pooled), on one seed per side" in text and "cell level" not in text.split("\n\n")[2]


def test_an_equal_candidate_is_not_flagged(tmp_path):
    base, cand = predictions_pair(
        tmp_path, n_cells=12, trials=40, cand_seeds=(0,), flip=0.0, unchanged_cells=0
    )
    cmp = compare(base, cand)
    assert cmp.unchanged and cmp.exit_code == 0 and cmp.pooled.empty
    assert len(comment_markdown(cmp).splitlines()) <= 8


def test_another_seed_is_compared_and_the_note_says_what_is_not_covered(tmp_path):
    base, cand = predictions_pair(tmp_path, n_cells=4, cand_seeds=(1,))
    cmp = compare(base, cand)
    assert len(cmp.cells) == 4 and set(cmp.cells["seed"]) == {"0 → 1"}
    assert cmp.cells["method"].str.startswith("over seeds and trials (1 → 1 seeds)").all()
    assert not cmp.retraining_covered
    text = comment_markdown(cmp)
    assert "retraining noise is not covered" in text and "--repeats 3" in text
    assert "retraining noise is not covered" in " ".join(json.loads(to_json(cmp))["notes"])


def test_repeats_on_both_sides_cover_retraining_noise(tmp_path):
    base, cand = predictions_pair(tmp_path, n_cells=3, base_seeds=(0, 1, 2), cand_seeds=(3, 4, 5))
    cmp = compare(base, cand)
    assert cmp.retraining_covered and (cmp.min_seeds_base, cmp.min_seeds_candidate) == (3, 3)
    assert cmp.cells["method"].str.startswith("over seeds and trials (3 → 3 seeds)").all()
    assert "retraining noise" not in comment_markdown(cmp)
    assert cmp.pooled["method"].iloc[0].endswith("and the seeds, crossed with the cells")
    # the seed variance pooled over the protocol's cells (its degrees of freedom summed): three
    # seeds a side narrow the typical cell against one seed per side (issue 35); a cell whose
    # own seeds scatter beyond chance keeps its own spread, and is wider
    one = compare(*predictions_pair(tmp_path / "one", n_cells=3, cand_seeds=(3,)))
    width = lambda c: (c.cells["d_accuracy_hi"] - c.cells["d_accuracy_lo"]).median()  # noqa: E731
    assert width(cmp) < width(one)


def test_the_same_seeds_on_both_sides_pair_seed_by_seed(tmp_path):
    """Both sides ran seeds 0, 1, 2 (the same splits): the cells pair the seeds, so the seeds'
    luck, which both sides share, cancels; other seeds stay unpaired. The pooled test crosses
    the seeds with the cells and pairs them too."""
    same = compare(
        *predictions_pair(
            tmp_path / "same", 3, base_seeds=(0, 1, 2), cand_seeds=(0, 1, 2), flip=0.1
        )
    )
    other = compare(
        *predictions_pair(
            tmp_path / "other", 3, base_seeds=(0, 1, 2), cand_seeds=(3, 4, 5), flip=0.1
        )
    )
    assert same.cells["method"].str.startswith("over seeds and trials (paired seed by seed)").all()
    # 12 trials a class: a drop of 7 points is too small to see against its tolerance of 1;
    # the comment says what the test could see and what would decide it
    assert same.state == "undecided" and same.pooled_regressions.empty
    acc = _pooled(same)
    assert acc["detectable"] > 2 * acc["tolerance"] and acc["seeds_needed"] > 3
    assert "points with 80 % power" in acc["undecided_reason"]
    assert f"about {acc['seeds_needed']} seeds per side" in comment_markdown(same)
    assert same.pooled["method"].iloc[0].endswith("crossed with the cells and paired seed by seed")
    assert other.pooled["method"].iloc[0].endswith("and the seeds, crossed with the cells")
    assert other.cells["method"].str.startswith("over seeds and trials (3 → 3 seeds)").all()
    # here the seeds' luck is small next to the flipped trials, so pairing has little to cancel:
    # each design pools its own seed spread over the cells, and the paired one is no wider to
    # speak of (strong luck, where pairing narrows: tests/stats/test_metrics.py)
    width = lambda c: (c.cells["d_accuracy_hi"] - c.cells["d_accuracy_lo"]).mean()  # noqa: E731
    assert width(same) < 1.1 * width(other)


def test_low_n_cells_are_inconclusive_and_never_the_worst(tmp_path):
    base, cand = predictions_pair(tmp_path, n_cells=5, trials=30, flip=0.3, low_n_cells=2)
    cmp = compare(base, cand, Gate.of(["accuracy"]))
    low = cmp.cells[cmp.cells["low_n"]]
    assert len(low) == 2 and (low["verdict"] == "inconclusive").all()
    assert low["inconclusive_reason"].str.startswith("low n").all()
    (line,) = summary(cmp).to_dict("records")
    assert line["inconclusive"] == 2 and line["worst_row"] not in set(low.index)
    # the cell family holds the 3 cells that changed and are not low-n
    assert cmp.level == pytest.approx(1 - CELL_ALPHA / 3)
    # folded: counted, not listed (issue 46: their intervals read like [-99.9, +91.9])
    text = comment_markdown(cmp)
    assert "? inconclusive (low n" not in text
    assert "2 low-n cells (fewer than 10 test trials of a class) not listed" in text


def test_a_wide_interval_is_inconclusive(tmp_path):
    base, cand = predictions_pair(tmp_path, n_cells=2, trials=24, flip=0.1)
    cmp = compare(base, cand, Gate(max_width=1))
    assert (cmp.cells["verdict"] == "inconclusive").all()
    assert cmp.cells["inconclusive_reason"].str.contains("wider than 1 points").all()


def test_identical_cells_leave_the_family(tmp_path):
    base, cand = predictions_pair(tmp_path, n_cells=6, flip=0.2, unchanged_cells=4)
    cmp = compare(base, cand)
    assert (cmp.cells["verdict"] == "identical").sum() == 4
    assert cmp.level == pytest.approx(1 - CELL_ALPHA / (2 * 3))  # 2 cells, 3 figures each
    pooled = _pooled(cmp)
    assert (pooled["cells"], pooled["changed_cells"]) == (6, 2)
    assert "≡ identical" not in comment_markdown(cmp).split("### Other cells")[-1]


def test_json_is_in_points_with_cells_as_objects_and_validates(tmp_path):
    import jsonschema  # the test extra installs it

    base, cand = predictions_pair(tmp_path, n_cells=4, flip=0.2, low_n_cells=1)
    cmp = compare(base, cand)
    doc = json.loads(to_json(cmp))
    schema = json.loads(
        resources.files("slipbench.report").joinpath("compare.schema.json").read_text()
    )
    jsonschema.validate(doc, schema)
    assert (
        doc["schema_version"] == SCHEMA_VERSION == schema["properties"]["schema_version"]["const"]
    )
    # the schema's figures are the gate's, as the results schema declares them
    pooled = schema["$defs"]["pooled"]["properties"]
    assert set(pooled["figure"]["enum"]) == set(DEFAULT_TOLERANCE)
    cell = doc["cells"][0]
    assert isinstance(cell["cell"], dict) and cell["cell"]["sensor_type"] == "Nano17"
    assert cell["d_accuracy"] == pytest.approx(100 * cmp.cells["d_accuracy"].iloc[0], abs=1e-3)
    assert 1 < cell["base_accuracy"] <= 100  # points, as the summary
    assert doc["pooled"][0]["figure"] == "accuracy"
    assert doc["pooled"][0]["change"] == pytest.approx(doc["summary"][0]["mean_change"], abs=1e-3)
    assert {"detectable", "resolution", "seeds_needed", "undecided_reason"} <= set(doc["pooled"][0])
    assert doc["verdict"] == "undecided" and doc["exit_code"] == 6
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate({**doc, "cells": [json.dumps(cell)]}, schema)  # a cell as a string


def test_a_seeds_luck_that_reaches_every_cell_stays_in_the_pooled_interval():
    """Each candidate seed moves every cell alike (one split, one set of draws per seed): with
    the seeds known to be crossed with the cells, the pooled interval keeps that luck whole;
    drawn cell by cell, it averages away over the cells."""
    rng = np.random.default_rng(5)
    luck = [0.25, -0.2, 0.0]  # per candidate seed: the share of windows it turns right / wrong
    cells = []
    for _ in range(8):
        base = _preds(rng) + _preds(rng)[:1]
        cells.append((base, [_lucky(rng, p, luck[k]) for k, p in enumerate(base)]))
    known = [CellSides(b, c, (0, 1, 2), (3, 4, 5)) for b, c in cells]
    unknown = [CellSides(b, c) for b, c in cells]
    a, b = pooled_change(known, seed=1, level=0.95), pooled_change(unknown, seed=1, level=0.95)
    assert a["d"] == pytest.approx(b["d"])
    assert a["seed_design"] == "the seeds, crossed with the cells"
    assert b["seed_design"].startswith("each cell's seeds, drawn on their own")
    assert a["hi"] - a["lo"] > 2 * (b["hi"] - b["lo"])


def test_a_pooled_change_over_many_cells_of_several_seeds_keeps_its_width():
    """Each cell's figures enter the two-level bootstrap scaled by 1 / cells (signs +-1): the
    seed-by-cluster correction of seeded_interval is then on the mean's scale. With the scale
    in the signs instead, it was 48 times too large and zeroed the interval of a null."""
    rng = np.random.default_rng(8)
    cells = [
        CellSides(_preds(rng) + _preds(rng)[:1], _preds(rng) + _preds(rng)[:1]) for _ in range(8)
    ]
    res = pooled_change(cells, seed=1, level=0.975)
    assert res["seeds"] and res["lo"] < res["d"] < res["hi"] and res["hi"] - res["lo"] > 0.02


def test_the_same_seeds_pair_in_the_pooled_test_and_their_shared_luck_cancels():
    """Both sides ran seeds 0, 1, 2 in every cell: seed k's split moves both sides' figures
    alike, so the pooled test pairs the seeds (one cell: exactly the cell's paired interval) and
    that luck cancels; drawn apart, it widens the interval."""
    rng = np.random.default_rng(11)
    luck = [0.3, -0.25, 0.05]  # per seed, shared by both sides
    cells = []
    for _ in range(6):
        base = _preds(rng) + _preds(rng)[:1]
        cand = [_lucky(rng, p, -0.05) for p in base]  # a slightly worse candidate
        sides = [[_lucky(rng, p, luck[k]) for k, p in enumerate(side)] for side in (base, cand)]
        cells.append(tuple(sides))
    same = [CellSides(b, c, (0, 1, 2), (0, 1, 2)) for b, c in cells]
    apart = [CellSides(b, c, (0, 1, 2), (3, 4, 5)) for b, c in cells]
    a, b = pooled_change(same, seed=2, level=0.95), pooled_change(apart, seed=2, level=0.95)
    assert a["d"] == pytest.approx(b["d"])
    assert a["seed_design"] == "the seeds, crossed with the cells and paired seed by seed"
    assert a["hi"] - a["lo"] < 0.5 * (b["hi"] - b["lo"])
    one = pooled_change(same[:1], seed=2, level=0.95)
    ref = over_seeds(*cells[0], seed=2, level=0.95, figures=("accuracy",), paired=True)
    assert (one["lo"], one["hi"]) == pytest.approx((ref["d_accuracy_lo"], ref["d_accuracy_hi"]))


def test_a_cell_skipped_under_one_seed_keeps_the_seeds_crossed_on_those_every_cell_ran():
    """One cell lacks seed 1 on both sides (skipped under that split): the pooled test keeps to
    seeds 0 and 2, which every cell ran, crossed and paired, so a split's luck that reaches every
    cell stays whole; drawn cell by cell it averaged away."""
    rng = np.random.default_rng(13)
    luck = [0.3, -0.25, 0.05]  # per seed: the split's luck, one input over the other
    cells = []
    for i in range(6):
        seeds = (0, 2) if i == 0 else (0, 1, 2)
        base = _preds(rng) + _preds(rng)[:1]
        cand = [_lucky(rng, base[k], luck[s]) for k, s in enumerate(seeds)]
        cells.append(CellSides(base[: len(seeds)], cand, seeds, seeds))
    kept = pooled_change(cells, seed=3, level=0.95)
    assert kept["seed_design"] == (
        "the seeds every cell ran (0, 2), crossed with the cells and paired seed by seed"
    )
    apart = pooled_change([CellSides(c.base, c.cand) for c in cells], seed=3, level=0.95)
    assert kept["hi"] - kept["lo"] > 2 * (apart["hi"] - apart["lo"])
    # not enough seeds in common: each cell's own
    few = [CellSides(c.base[:1], c.cand[:1], (i,), (i,)) for i, c in enumerate(cells)]
    assert pooled_change(few, seed=3, level=0.95)["seed_design"].startswith("each cell's seeds")
