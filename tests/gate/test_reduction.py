"""What the reduction keeps: channels cells paired with their univariate twins, window by window
and over seeds, pooled per protocol and sensor type, and read by the pooled intervals."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from resultgen import fake_rows, inputs_folder

from slipbench.gate.reduction import compare_inputs, has_both_inputs, inputs, twin_key
from slipbench.stats.metrics import paired_comparison
from slipbench.store.results import read_predictions


def _pooled(cmp, sensor: str) -> dict:
    (line,) = cmp.pooled[cmp.pooled["sensor_type"] == sensor].to_dict("records")
    return line


@pytest.mark.parametrize(
    "kwargs",
    [
        {"model_noise": 0.0},  # one seed: window by window
        {"seeds": (0, 1, 2)},  # retrained models differ: seeds are a factor
    ],
    ids=["one-seed", "three-seeds"],
)
def test_channels_better_on_one_sensor_equal_on_the_other(tmp_path, kwargs):
    folder, rows = inputs_folder(tmp_path, **kwargs)
    cmp = compare_inputs(rows, [folder])
    assert len(cmp.cells) == 14  # 2 sensors x 2 fingers x 4 windows, less the two unpaired
    better, equal = _pooled(cmp, "Nano17"), _pooled(cmp, "BioTacSP")
    seeds = len(kwargs.get("seeds", (0,)))
    # one seed per side: its interval holds the test noise only, so nothing is read from it
    assert better["reading"] == ("channels better" if seeds > 1 else "inconclusive")
    assert better["d_accuracy_lo"] > 0.01
    assert better["d_tp_rate_lo"] > 0 and better["d_tn_rate_lo"] > 0
    assert equal["reading"] == ("undecided" if seeds > 1 else "inconclusive")
    assert equal["d_accuracy_lo"] < 0 < equal["d_accuracy_hi"]
    assert better["cells"] == equal["cells"] == 7
    # two pooled changes: each at 97.5 %, together at 95 %
    assert cmp.pooled_level == pytest.approx(0.975) and cmp.level == pytest.approx(0.95)
    method = "paired over trials" if seeds == 1 else "over seeds and trials (paired seed by seed)"
    assert cmp.cells["method"].str.startswith(method).all()
    assert ("crossed with the cells and paired seed by seed" in better["method"]) == (seeds > 1)


#: the luck a seed's split gives one input over the other, in every cell of a sensor at once
SPLIT_NOISE = 0.15


@pytest.mark.slow
def test_seeds_bring_retraining_noise_into_the_interval(tmp_path):
    """Equal inputs whose models differ by training and by their seed's split alone: three seeds
    widen the interval by the seeds' spread, and it holds 0."""
    folder, rows = inputs_folder(tmp_path / "one", seeds=(0,), split_noise=SPLIT_NOISE)
    one = _pooled(compare_inputs(rows, [folder]), "BioTacSP")
    folder, rows = inputs_folder(tmp_path / "three", seeds=(0, 1, 2), split_noise=SPLIT_NOISE)
    three = _pooled(compare_inputs(rows, [folder]), "BioTacSP")
    assert three["reading"] == "undecided"
    width = [100 * (r["d_accuracy_hi"] - r["d_accuracy_lo"]) for r in (one, three)]
    assert width[1] > width[0]


@pytest.mark.slow
def test_equal_inputs_are_rarely_read_as_different(tmp_path):
    """A null study: both sensors equal on both inputs, retraining noise N(0, 0.3) on the logit
    per model and a split's luck N(0, 0.15) per seed shared by a sensor's cells, 20 replications
    x 2 sensors = 40 pooled readings, each at 97.5 % (2 per comparison). With three seeds, crossed
    with the cells and paired, 1 of 40 called a difference (9 inconclusive: three splits pin the
    split's luck down loosely); with one seed the split's luck is outside the intervals: 10 of 40,
    which the section says when it runs on one seed. Drawn cell by cell, three seeds called 6 of
    80 at a split's luck of 0.3 (crossed: 0 of 80)."""
    called = {}
    for seeds in ((0, 1, 2), (0,)):
        readings = []
        for rep in range(20):
            folder, rows = inputs_folder(
                tmp_path / f"{len(seeds)}-{rep}",
                seeds=seeds,
                boost={"Nano17": 0.0, "BioTacSP": 0.0},
                replicate=rep,
                split_noise=SPLIT_NOISE,
            )
            readings += list(compare_inputs(rows, [folder]).pooled["reading"])
        called[len(seeds)] = sum(r in ("channels better", "channels worse") for r in readings)
    assert called[3] <= 2  # at most 5 % of 40
    assert called[1] == 0  # one seed: inconclusive, whatever its interval (read alone: 10 of 40)


def test_a_cell_is_paired_window_by_window_as_compare_pairs_it(tmp_path):
    folder, rows = inputs_folder(tmp_path, model_noise=0.0)
    cmp = compare_inputs(rows, [folder])
    cell = cmp.cells.iloc[0]
    assert cell["d_accuracy"] == pytest.approx(
        cell["channels_accuracy"] - cell["univariate_accuracy"]
    )
    twins = rows[rows["cell"].map(lambda c: "index" in c and '"window": 25' in c)]
    twins = twins[twins["sensor_type"] == cell["sensor_type"]]
    uni, ch = (
        read_predictions(folder, k) for k in twins.sort_values("input", na_position="first")["key"]
    )
    joined = uni.merge(ch, on=["recording_id", "window_index"], suffixes=("_u", "_c"))
    direct = paired_comparison(
        joined["y_true_u"].to_numpy(),
        joined["score_u"].to_numpy() >= 0.5,
        joined["score_c"].to_numpy() >= 0.5,
        joined["trial_u"].to_numpy(),
        seed=0,
        base_scores=joined["score_u"].to_numpy(),
        cand_scores=joined["score_c"].to_numpy(),
    )
    for bound in ("", "_lo", "_hi"):
        assert cell[f"d_accuracy{bound}"] == pytest.approx(direct[f"d_accuracy{bound}"])


def test_cells_without_a_twin_are_listed_with_the_reason(tmp_path):
    folder, rows = inputs_folder(tmp_path)
    # a univariate-only detector beside it is no part of the comparison
    rows = pd.concat([rows, fake_rows("window-size", "holweg")], ignore_index=True)
    cmp = compare_inputs(rows, [folder])
    reasons = dict(zip(cmp.unpaired["sensor_type"], cmp.unpaired["reason"]))
    assert reasons == {
        "Nano17": "no univariate twin: the univariate run holds no such cell",
        "BioTacSP": "channels skipped (units differ in channels)",
    }
    assert set(cmp.unpaired["detector"]) == {"tcn"}
    assert set(cmp.unpaired["inputs"]) == {"channels", "univariate, channels"}
    assert (cmp.unpaired["cell"].str.contains('"window": 200')).all()
    assert not cmp.unpaired["cell"].str.contains("input").any()  # named as the twins share it


def test_old_rows_without_the_column_are_univariate(tmp_path):
    folder, rows = inputs_folder(tmp_path, legacy=True)
    assert rows.loc[rows["input"].isna()].shape[0] > 0  # the univariate rows lack it
    assert set(inputs(rows)) == {"univariate", "channels"}
    assert has_both_inputs(rows)
    old = fake_rows("window-size")  # no input column at all
    assert "input" not in old and set(inputs(old)) == {"univariate"}
    assert not has_both_inputs(old)
    # the twin key leaves the input out, also where the cell key names it
    ch = rows[rows["input"] == "channels"].iloc[1].to_dict()
    assert '"input": "channels"' in ch["cell"]
    same = rows[
        rows["input"].isna()
        & (rows["sensor_type"] == ch["sensor_type"])
        & (rows["sensor_instance"] == ch["sensor_instance"])
    ]
    keys = {w: twin_key(r) for w, r in zip(same["window"], same.to_dict("records"))}
    assert [w for w, k in keys.items() if k == twin_key(ch)] == [ch["window"]]
    written = folder / "results.parquet"
    assert compare_inputs(pd.read_parquet(written), [folder]).cells.shape[0] == 14


def test_without_predictions_the_rows_decide(tmp_path):
    folder, rows = inputs_folder(tmp_path, model_noise=0.0, predictions=False)
    cmp = compare_inputs(rows, [folder])
    assert (cmp.cells["method"] == "unpaired").all()
    assert cmp.pooled["method"].str.startswith("mean of the cells' standard errors").all()
    better, equal = _pooled(cmp, "Nano17"), _pooled(cmp, "BioTacSP")
    assert better["d_accuracy_lo"] > 0.01 and better["reading"] == "inconclusive"  # one seed
    assert equal["d_accuracy_lo"] < 0 < equal["d_accuracy_hi"]
    # the rows' intervals err wide: wider than the paired ones
    paired = compare_inputs(*_with_predictions(tmp_path / "paired"))
    assert _width(cmp) > _width(paired)


def _with_predictions(root):
    folder, rows = inputs_folder(root, model_noise=0.0)
    return rows, [folder]


def _width(cmp) -> float:
    return float(np.mean(cmp.pooled["d_accuracy_hi"] - cmp.pooled["d_accuracy_lo"]))


def test_nothing_to_compare_without_channels():
    cmp = compare_inputs(fake_rows("window-size"))
    assert cmp.cells.empty and cmp.pooled.empty and cmp.unpaired.empty
