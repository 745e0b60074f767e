"""The gate's noise from outside a comparison (a calibration: any NoiseSource) and its looks at
more seeds: which look stored seeds make, each look's level, and when an interim look passes.
Small synthetic result folders with predictions (tests/resultgen.py:predictions_pair)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from resultgen import predictions_pair
from scipy.stats import t as student_t

from slipbench.gate.compare import (
    POOLED_ALPHA,
    Look,
    _pooled_verdict,
    compare,
    look_at,
    look_level,
    measured_noise,
)
from slipbench.gate.gate import Gate
from slipbench.stats.contrast import family_level
from slipbench.stats.noise import SeedNoise, combined


class Source:
    """A NoiseSource answering ``variance`` on ``df`` for every figure, keeping what it was
    asked (detector, protocol, figure, cell, paired)."""

    def __init__(self, variance: float, df: float = 40.0, name: str = "a measured source"):
        self.noise = SeedNoise(variance, df, name)
        self.asked: list[tuple] = []

    def seed_noise(self, detector, protocol, figure, cell, paired):
        self.asked.append((detector, protocol, figure, cell, paired))
        return self.noise


class Silent:
    def seed_noise(self, detector, protocol, figure, cell, paired):
        return None


def _acc(cmp):
    (row,) = cmp.pooled[cmp.pooled["figure"] == "accuracy"].to_dict("records")
    return row


def test_sources_are_combined_by_their_degrees_of_freedom():
    a, b = SeedNoise(1.0, 10, "the bench's calibration"), SeedNoise(4.0, 30, "the history")
    both = combined([a, b])
    assert both is not None
    assert both.variance == pytest.approx((10 * 1.0 + 30 * 4.0) / 40) and both.df == 40
    assert both.source == "the bench's calibration and the history"
    assert combined([]) is None
    assert measured_noise([Silent(), Source(2.0, 5)], ("d", "p", None), "accuracy", True) == (
        SeedNoise(2.0, 5, "a measured source")
    )


@pytest.mark.parametrize(
    ("cand_seeds", "paired"), [((0, 1, 2), True), ((3, 4, 5), False)], ids=["same", "apart"]
)
def test_a_measured_noise_replaces_the_sides_own_spread_and_stays_paired(
    tmp_path, cand_seeds, paired
):
    """The source is asked per cell and per protocol's mean, for the design the seeds make
    (paired where both sides ran the same seeds); a large measured variance widens both the
    cells' and the pooled test's intervals, and the pooled test names its source."""
    sides = predictions_pair(
        tmp_path, n_cells=3, base_seeds=(0, 1, 2), cand_seeds=cand_seeds, flip=0.05
    )
    own = compare(*sides)
    loud = Source(0.04)  # a 20-point seed SD
    measured = compare(*sides, sources=[loud])
    assert {a[4] for a in loud.asked} == {paired}
    assert {a[3] for a in loud.asked} >= {None, *map(str, own.cells["cell"])}
    width = lambda c: (c.cells["d_accuracy_hi"] - c.cells["d_accuracy_lo"]).mean()  # noqa: E731
    assert width(measured) > 1.2 * width(own)
    wide, narrow = _acc(measured), _acc(own)
    assert wide["change_hi"] - wide["change_lo"] > 2 * (narrow["change_hi"] - narrow["change_lo"])
    assert wide["noise"] == "a measured source" and narrow["noise"] == ""
    assert measured.measured == "a measured source" and own.measured == ""


def test_a_measured_noise_with_many_degrees_of_freedom_narrows_three_seeds(tmp_path):
    """Three seeds a side carry two degrees of freedom; the same variance measured on forty
    gives a smaller t quantile, so the pooled interval narrows."""
    sides = predictions_pair(tmp_path, n_cells=3, base_seeds=(0, 1, 2), cand_seeds=(3, 4, 5))
    own = _acc(compare(*sides))
    var = (own["change_se"] / 100) ** 2 * 3 / 2  # about the sides' own seed variance
    measured = _acc(compare(*sides, sources=[Source(var, df=400)]))
    assert measured["df"] > own["df"]
    assert measured["change_hi"] - measured["change_lo"] < own["change_hi"] - own["change_lo"]


def test_the_look_is_the_last_one_the_stored_seeds_reach():
    gate = Gate(seeds=3, budget=12)
    assert look_at(gate, 3) == Look(0, 3, False, 6)
    assert look_at(gate, 7) == Look(1, 7, False, 9)
    assert look_at(gate, 2) == Look(0, 2, False, 3)  # short of the first look: its seeds next
    assert look_at(gate, 12) == Look(3, 12, True, 0)
    assert look_at(Gate(), 3) == Look(0, 3, True, 0)  # no budget: one look
    assert look_at(Gate(seeds=3, budget=3), 3).final


def test_each_look_spends_its_share_and_one_look_is_bonferroni():
    assert look_level(Gate(), look_at(Gate(), 3), 3, POOLED_ALPHA) == family_level(3, POOLED_ALPHA)
    gate = Gate(seeds=3, budget=12)
    levels = [look_level(gate, look_at(gate, n), 3, POOLED_ALPHA) for n in (3, 6, 9, 12)]
    # O'Brien-Fleming: the first look is far stricter, the last a little stricter than one look
    assert levels[0] > levels[1] > levels[2] > levels[3] > family_level(3, POOLED_ALPHA)
    assert 1 - levels[0] < (1 - family_level(3, POOLED_ALPHA)) / 100


def _row(**kw):
    row = {
        "figure": "accuracy",
        "tolerance": 1.5,
        "change_lo": -8.0,
        "change_hi": 9.0,
        "read_lo": -0.8,
        "read_hi": 0.9,
        "look_level": 0.999997,
        "flags": False,
        "low_n": False,
        "seeds": 3,
        "resolution": 0.5,
        "detectable": 2.0,
        "final": False,
        "next_seeds": 6,
        "bound": 0.8,
    }
    return row | kw


def test_an_interim_look_passes_only_where_the_drops_bound_lies_inside_the_tolerance():
    assert _pooled_verdict(_row(), True) == ("within margin", "")
    verdict, why = _pooled_verdict(_row(read_lo=-1.9, bound=1.9), True)
    # a power rule would pass it (resolution 0.5 <= 1.5): at an interim look it is undecided
    assert verdict == "undecided"
    assert "a drop of up to 1.9 points is not ruled out at 3 seeds a side" in why
    assert "the next look runs 6" in why
    # the last look: the power rule
    last = dict(final=True, change_lo=-1.9, change_hi=0.9, read_lo=-1.9, bound=1.9)
    assert _pooled_verdict(_row(**last), True)[0] == "no significant change"
    assert _pooled_verdict(_row(**last, resolution=2.0), True)[0] == "undecided"
    # a flagged change is flagged at any look
    flagged = dict(change_lo=-4.0, change_hi=-2.0, read_lo=-4.0, read_hi=-2.0, bound=4.0)
    assert _pooled_verdict(_row(**flagged, flags=True), True)[0] == "regressed"


def test_an_interim_look_never_calls_a_drop_beyond_its_tolerance_no_change():
    """The family's interval lies beyond the tolerance, the look's does not flag it: undecided,
    with the look's own interval and level said. At the last look a drop shown but not beyond
    the tolerance is "worse"; a gain beyond it that the look does not flag is "better"."""
    verdict, why = _pooled_verdict(_row(read_lo=-5.4, read_hi=-2.3, bound=5.4), True)
    assert verdict == "undecided"
    assert "not flagged at this look" in why and "99.9997 %" in why and "[-8, +9]" in why
    worse = _row(final=True, read_lo=-2.0, read_hi=-0.1, bound=2.0)
    assert _pooled_verdict(worse, True) == ("worse", "")
    assert _pooled_verdict(_row(read_lo=2.0, read_hi=4.0, bound=-2.0), True) == ("better", "")


def test_compare_decides_at_the_look_of_its_seeds(tmp_path):
    """The same sides under a gate of looks: the pooled test's bound is the family's, the
    interval the look's (wider at the first look than under one look)."""
    sides = predictions_pair(
        tmp_path, n_cells=3, base_seeds=(0, 1, 2), cand_seeds=(0, 1, 2), flip=0.05
    )
    once = compare(*sides, Gate.of(["accuracy"], accuracy=1.5))
    looks = compare(*sides, Gate({"accuracy": 1.5}, seeds=3, budget=12))
    assert looks.look == Look(0, 3, False, 6) and once.look.final
    a, b = _acc(once), _acc(looks)
    assert b["change_hi"] - b["change_lo"] > a["change_hi"] - a["change_lo"]
    q = student_t.ppf(1 - POOLED_ALPHA / 2, b["df"])  # one pooled test: the family's level
    assert b["bound"] == pytest.approx(-b["change"] + q * b["change_se"])
    assert b["final"] == np.False_ and b["next_seeds"] == 6
    # the interval the verdict reads is the family's where the look flags nothing, and its
    # worse end is the drop ruled out
    if not b["flags"]:
        assert b["read_level"] == pytest.approx(family_level(1, POOLED_ALPHA))
        assert b["read_lo"] == pytest.approx(b["change"] - q * b["change_se"])
        assert b["bound"] == pytest.approx(-b["read_lo"])


def test_a_regressed_row_names_each_figure_with_its_own_change():
    from slipbench.report.compare import _regressed_figures

    row = {
        "regressed_figures": "tn_rate",
        "d_tn_rate": -0.16,
        "d_tn_rate_lo": -0.221,
        "d_tn_rate_hi": -0.098,
        "d_accuracy": -0.003,
    }
    assert _regressed_figures(row) == ": TN rate (false alarms) -16.0 [-22.1, -9.8]"
    # the figure the row's Δ column shows is named only
    both = row | {"regressed_figures": "accuracy, tn_rate"}
    assert _regressed_figures(both) == ": accuracy, TN rate (false alarms) -16.0 [-22.1, -9.8]"
    assert _regressed_figures({"regressed_figures": ""}) == ""


def _shared_pair(tmp_path):
    """A pair whose every window-size cell is also a cross-instance cell: the same models
    (model keys) tested on the same test set, under another protocol and key."""
    import shutil

    import pandas as pd

    base, cand = predictions_pair(
        tmp_path, n_cells=3, base_seeds=(0, 1, 2), cand_seeds=(0, 1, 2), flip=0.1
    )
    for folder in (base, cand):
        rows = pd.read_parquet(folder / "results.parquet")
        rows["model_key"] = "m-" + rows["key"]
        rows["test_sensors"] = '["Nano17 index"]'
        twin = rows.assign(protocol="cross-instance", key="x-" + rows["key"])
        for key in rows["key"]:
            shutil.copy(
                folder / "predictions" / f"{key}.parquet",
                folder / "predictions" / f"x-{key}.parquet",
            )
        pd.concat([rows, twin], ignore_index=True).to_parquet(folder / "results.parquet")
    return base, cand


def test_a_cell_two_protocols_share_is_one_test_and_listed_once(tmp_path):
    from slipbench.report.compare import comment_markdown

    alone = compare(
        *predictions_pair(
            tmp_path / "alone", n_cells=3, base_seeds=(0, 1, 2), cand_seeds=(0, 1, 2), flip=0.1
        )
    )
    both = compare(*_shared_pair(tmp_path / "shared"))
    assert len(both.cells) == 6
    shared = both.cells.set_index("protocol")["shared_with"]
    assert (shared["cross-instance"] == "window-size").all() and (shared["window-size"] == "").all()
    # the family counts each cell once: the same level as the three cells alone
    assert both.level == pytest.approx(alone.level)
    text = comment_markdown(both)
    assert (
        "3 cells of cross-instance are window-size's (the same models tested on the same test set)"
        in text
    )


def test_a_calibration_of_zero_seed_noise_never_narrows_an_interval(tmp_path):
    """A deterministic detector's calibration says 0 (its twin equals its run), yet the
    change's test trials leave it uncertain: the pooled tests and the cells keep their
    cluster-bootstrap variance, and no pooled interval is narrower than without it."""
    sides = predictions_pair(
        tmp_path, n_cells=3, base_seeds=(0, 1, 2), cand_seeds=(0, 1, 2), flip=0.1
    )
    own = compare(*sides)
    zero = compare(*sides, sources=[Source(0.0, df=20)])
    for a, b in zip(own.pooled.to_dict("records"), zero.pooled.to_dict("records")):
        assert b["change_se"] > 0 and b["change_hi"] - b["change_lo"] > 0
        assert b["change_hi"] - b["change_lo"] >= (a["change_hi"] - a["change_lo"]) * (1 - 1e-9)
    for f in ("accuracy", "tn_rate", "tp_rate"):
        # a cell's own seed spread may be below the protocol's pooled one (which the
        # calibration replaces): its interval keeps its trials' variance, never a point
        assert (zero.cells[f"d_{f}_se"] > 0.01).all()
        assert (zero.cells[f"d_{f}_hi"] - zero.cells[f"d_{f}_lo"] > 0.05).all()


def test_one_seed_with_a_calibration_of_zero_keeps_the_test_trials_interval():
    """A contrast of one seed per side decides on a measured seed noise; where that is 0 its
    interval is the test trials' alone, never narrower."""
    from slipbench.stats.contrast import from_parts, from_rows

    terms = pd.DataFrame(
        {"unit": ["a", "a"], "seed": [0, 0], "weight": [-1.0, 1.0], "mean": [0.8, 0.77],
         "se": [0.02, 0.02]}
    )  # fmt: skip
    alone = from_rows(terms)
    zero = from_rows(terms, noise=SeedNoise(0.0, 20, "the bench's calibration"))
    assert alone.missing and not zero.missing  # it decides now, on the trials' noise
    tests = from_parts(alone.estimate, [(alone.se**2, np.inf)])
    assert zero.hi - zero.lo >= (tests.hi - tests.lo) * (1 - 1e-12) > 0


def _cell(read_at_look=True, **changes):
    """A compared cell's row: ``figure=(change, lo, hi)`` in points."""
    row = {
        "base_status": "ok",
        "candidate_status": "ok",
        "identical": False,
        "low_n": False,
        "stream": False,
        "method": "paired",
        "read_at_look": read_at_look,
    }
    for f in ("accuracy", "tn_rate", "tp_rate"):
        d, lo, hi = changes.get(f, (0.0, -1.0, 1.0))
        row |= {f"d_{f}": d / 100, f"d_{f}_lo": lo / 100, f"d_{f}_hi": hi / 100}
    return row


@pytest.mark.parametrize(
    ("changes", "verdict"),
    [
        # a TN drop its interval shows, not beyond the tolerance: never "no significant change"
        ({"tn_rate": (-3.9, -5.4, -2.3)}, "worse"),
        # better beyond the tolerance on TP, 12.6 points of TN rate lost: mixed, not improved
        ({"tp_rate": (9.0, 5.0, 13.0), "tn_rate": (-12.6, -30.0, 4.0)}, "mixed"),
        # a TN drop inside its tolerance leaves the gain an improvement
        ({"tp_rate": (9.0, 5.0, 13.0), "tn_rate": (-1.0, -2.5, -0.2)}, "improved"),
        ({"tp_rate": (9.0, 5.0, 13.0), "tn_rate": (-2.0, -3.5, -0.5)}, "mixed"),
        ({"tp_rate": (9.0, 5.0, 13.0)}, "improved"),
        ({"tp_rate": (2.0, 0.5, 3.5)}, "better"),
        ({"tn_rate": (-9.0, -13.0, -5.0), "tp_rate": (9.0, 5.0, 13.0)}, "regressed"),
        ({"accuracy": (0.1, -0.5, 0.7)}, "within margin"),
        ({"tn_rate": (-1.0, -4.0, 2.0)}, "no significant change"),
    ],
)
def test_a_cells_word_matches_its_intervals(changes, verdict):
    from slipbench.gate.compare import _judge_cells

    gate = Gate({"accuracy": 1.5, "tn_rate": 3.0, "tp_rate": 3.0})
    judged = _judge_cells(pd.DataFrame([_cell(**changes)]), gate)
    assert judged["verdict"].iloc[0] == verdict


def test_a_cell_the_look_does_not_flag_is_worse_not_regressed():
    """Before the last look a cell's interval at the family's level lying beyond the
    tolerance is worse (the look did not flag it), and says so; at the look it regresses."""
    from slipbench.gate.compare import BEYOND_UNFLAGGED, _judge_cells

    gate = Gate({"accuracy": 1.5, "tn_rate": 3.0, "tp_rate": 3.0}, seeds=3, budget=12)
    beyond = {"tn_rate": (-9.0, -13.0, -5.0)}
    judged = _judge_cells(pd.DataFrame([_cell(False, **beyond), _cell(True, **beyond)]), gate)
    assert judged["verdict"].tolist() == ["worse", "regressed"]
    assert judged["inconclusive_reason"].iloc[0] == BEYOND_UNFLAGGED
    assert judged["regressed_figures"].tolist() == ["", "tn_rate"]


def test_a_level_is_never_printed_as_100_percent():
    from slipbench.gate.compare import level_text

    assert level_text(0.95) == "95 %"
    assert level_text(1 - 0.025 / 12) == "99.79 %"
    assert level_text(1 - 2.6e-7) == "99.999974 %"
    assert level_text(1 - 1e-12) != "100 %" and "100 %" not in level_text(1.0)


def test_a_power_beyond_a_rates_range_cannot_see_a_drop_of_any_size():
    from slipbench.report.compare import _sees

    assert _sees({"figure": "tp_rate", "detectable": 310.0, "final": False}) == (
        "cannot see a drop of any size at this look"
    )
    assert _sees({"figure": "tp_rate", "detectable": 4.5, "final": True}) == "4.5 points"
    assert _sees({"figure": "median_delay_ms", "detectable": 310.0, "final": True}) == "3.1e+02 ms"


def test_the_comment_at_a_first_look_rules_out_only_what_its_printed_interval_does(tmp_path):
    """At the first of four looks: every pooled line's "ruled out" bound is the worse end of
    the interval printed beside it, at a level printed below 100 %."""
    import re

    from slipbench.report.compare import comment_markdown

    sides = predictions_pair(
        tmp_path, n_cells=3, base_seeds=(0, 1, 2), cand_seeds=(0, 1, 2), flip=0.05
    )
    gate = Gate({"accuracy": 10.0, "tn_rate": 16.0, "tp_rate": 16.0}, seeds=3, budget=12)
    cmp = compare(*sides, gate)
    text = comment_markdown(cmp)
    assert "100 %" not in text and not re.search(r"\b\d\.\de\+0[2-9] points", text)
    said = re.findall(
        r"([+-][\d.]+(?:e[+-]\d+)?) \[([+-][\d.e+-]+), ([+-][\d.e+-]+)\] points \(([\d.]+) %\): "
        r"a drop (?:beyond ([\d.e+-]+) points|of any size) ruled out",
        text,
    )
    assert len(said) == len(cmp.pooled) > 0, text
    for _, lo, _, level, bound in said:
        assert float(level) < 100
        assert (float(bound) if bound else 0.0) == pytest.approx(max(0.0, -float(lo)))


def test_a_no_regression_line_prints_its_interval_and_reads_its_bound_from_it():
    from slipbench.report.compare import _seen

    row = {
        "figure": "tp_rate",
        "protocol": "cross-instance",
        "detector": "holweg",
        "change": 0.039,
        "read_lo": -0.39,
        "read_hi": 0.47,
        "read_level": 1 - 0.025 / 3,
        "bound": 0.39,
        "detectable": 310.0,
    }
    interval = "+0.039 [-0.39, +0.47] points (99.17 %)"
    assert _seen(row | {"final": False}) == (
        f"TP rate (misses) of cross-instance, holweg {interval}: a drop beyond 0.39 points "
        "ruled out"
    )
    assert _seen(row | {"final": False, "bound": -0.1}).endswith("a drop of any size ruled out")
    assert _seen(row | {"final": True}).endswith(f"{interval}: it cannot see a drop of any size")
    assert _seen(row | {"final": True, "detectable": 4.2}).endswith(
        "a drop of 4.2 points would show (80 % power)"
    )
