"""The random-effects verdict across datasets: known effects recovered, degenerate cases said."""

from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
from resultgen import fake_rows
from scipy.stats import t as student_t
from statsmodels.stats.meta_analysis import combine_effects

from slipbench.report.meta import summary_table
from slipbench.seeding import rng_for
from slipbench.stats.contrast import pair_seeds, paired_change
from slipbench.stats.meta import meta_analysis, pool, transferred

FIGURES = ("accuracy", "tp_rate", "tn_rate")


def shifted(rows: pd.DataFrame, detector: str, shift: float) -> pd.DataFrame:
    """``rows`` as another detector's, every figure and bound moved by ``shift``: its true change."""
    out = rows.assign(detector=detector, key=rows["key"] + detector)
    for name in FIGURES:
        for col in (name, f"{name}_lo", f"{name}_hi"):
            out[col] = rows[col] + shift
    return out


def dataset(fingerprint: str, shift: float) -> tuple[pd.DataFrame, pd.DataFrame]:
    base = fake_rows("speed-holdout", "features").head(12).assign(dataset_fingerprint=fingerprint)
    return base, shifted(base, "holweg", shift)


def test_two_datasets_of_known_effects_are_recovered_within_their_intervals():
    effects = {"sim": 0.06, "dos": 0.02}
    m = meta_analysis({n: dataset(n, e) for n, e in effects.items()}, ("features", "holweg"))
    for line in m.datasets.to_dict("records"):
        truth = effects[line["dataset"]]
        assert line["lo"] < truth < line["hi"]
        assert abs(line["d"] - truth) < 1e-9
        assert line["reason"] == ""
    assert m.pooled_over == 2
    # both datasets have one standard error v^0.5 (the same rows moved), so the weights are
    # equal and Paule-Mandel solves (y1 - y2)^2 / (2 (v + tau2)) = 1: the pooled change is the
    # mean of the true ones and tau2 their variance (ddof 1) less the sampling variance
    v = float(m.datasets["se"].iloc[0]) ** 2
    assert np.allclose(m.datasets["se"], v**0.5)
    truths = np.array(list(effects.values()))
    assert abs(m.d - truths.mean()) < 1e-9
    assert 0 < v < truths.var(ddof=1)  # else the known spread would not show at all
    assert abs(m.tau2 - (truths.var(ddof=1) - v)) < 1e-9
    assert abs(m.i2 - m.tau2 / (m.tau2 + v)) < 1e-6
    # one seed each: the datasets' intervals are normal (df inf), and the pooled interval's
    # degrees of freedom are tau²'s one, weighed by Welch-Satterthwaite: ((v + tau²) / tau²)²
    df = ((v + m.tau2) / m.tau2) ** 2
    half = student_t.ppf(0.975, df) * np.sqrt((v + m.tau2) / 2)
    assert abs(m.df - df) < 1e-6
    assert abs(m.lo - (m.d - half)) < 1e-6 and abs(m.hi - (m.d + half)) < 1e-6


def test_known_effects_under_cell_noise_are_recovered_within_their_intervals():
    """Each cell's change is its dataset's true one plus noise (SD 1 point): every dataset's
    interval and the pooled one hold the truth, and where both datasets share one true change
    tau2 comes out 0."""
    for effects, spread in (
        ({"sim": 0.06, "dos": 0.02}, True),
        ({"sim": 0.03, "dos": 0.03}, False),
    ):
        per = {}
        for name, effect in effects.items():
            base, cand = dataset(name, effect)
            noise = rng_for(0, "test-meta", name).normal(0, 0.01, len(cand))
            per[name] = (base, cand.assign(accuracy=cand["accuracy"] + noise))
        m = meta_analysis(per, ("features", "holweg"))
        for line in m.datasets.to_dict("records"):
            assert line["lo"] < effects[line["dataset"]] < line["hi"]
        assert m.lo < np.mean(list(effects.values())) < m.hi
        assert (m.tau2 > 0) == spread and (m.i2 > 0) == spread


def test_pool_agrees_with_a_fixed_effect_where_datasets_agree():
    res = pool([0.03, 0.03, 0.03], [0.01, 0.02, 0.01], [np.inf, np.inf, np.inf])
    assert res["tau2"] == 0 and res["i2"] == 0
    assert abs(res["d"] - 0.03) < 1e-12 and res["lo"] < 0.03 < res["hi"]


def test_one_dataset_gives_its_change_and_no_pooled_one():
    m = meta_analysis({"sim": dataset("sim", 0.04)}, ("features", "holweg"))
    assert len(m.datasets) == 1 and np.isfinite(m.datasets["d"].iloc[0])
    assert np.isnan(m.d) and m.pooled_over == 1
    assert any("no pooled change" in n for n in m.notes)


def test_a_pair_missing_on_one_dataset_is_said_not_pooled():
    base, _ = dataset("dos", 0.0)
    per = {"sim": dataset("sim", 0.04), "dos": (base, base.iloc[:0]), "lab": dataset("lab", 0.01)}
    m = meta_analysis(per, ("features", "holweg"))
    dos = m.datasets.set_index("dataset").loc["dos"]
    assert dos["n_cells"] == 0 and "no cell" in dos["reason"]
    assert m.pooled_over == 2 and np.isfinite(m.d)


def test_a_dataset_of_cells_stored_twice_says_so():
    base, cand = dataset("dos", 0.02)
    twice = pd.concat([base, base.assign(key=base["key"] + "-rerun")])
    per = {"sim": dataset("sim", 0.04), "dos": (twice, cand)}
    dos = meta_analysis(per, ("features", "holweg")).datasets.set_index("dataset").loc["dos"]
    assert dos["reason"] == (
        f"no cell and seed both finished ({len(base)} cells holding a seed stored twice on a side)"
    )
    partly = pd.concat([base, base.head(3).assign(key=base["key"].head(3) + "-rerun")])
    m = meta_analysis({"sim": dataset("sim", 0.04), "dos": (partly, cand)}, ("features", "holweg"))
    assert m.datasets.set_index("dataset").loc["dos", "n_cells"] == len(base) - 3
    assert "dos: left out: 3 cells holding a seed stored twice on a side." in m.notes


def test_zero_variance_is_left_out_with_its_reason():
    base, cand = dataset("sim", 0.0)
    flat = cand.copy()
    for name in FIGURES:  # no spread at all: bounds equal to the figure
        flat[f"{name}_lo"] = flat[f"{name}_hi"] = flat[name]
    base_flat = base.copy()
    for name in FIGURES:
        base_flat[f"{name}_lo"] = base_flat[f"{name}_hi"] = base_flat[name]
    per = {"sim": (base_flat, flat), "dos": dataset("dos", 0.02), "lab": dataset("lab", 0.03)}
    m = meta_analysis(per, ("features", "holweg"))
    sim = m.datasets.set_index("dataset").loc["sim"]
    assert "zero standard error" in sim["reason"]
    assert m.pooled_over == 2 and np.isfinite(m.lo)


def test_pairing_keeps_inputs_and_seeds_apart():
    base = fake_rows("window-size", "features", seeds=(0, 1)).head(12)
    cand = shifted(base, "tcn", 0.05)
    both = pd.concat([base, base.assign(input="channels", accuracy=base["accuracy"] - 0.5)])
    change = paired_change(
        pair_seeds(both, cand)
    )  # cand has univariate rows only: pairs with those
    assert change.n_cells == base["cell"].nunique() and change.seeds == (0, 1)
    assert abs(change.estimate - 0.05) < 1e-9 and change.lo < 0.05 < change.hi


def test_transfer_rows_are_marked_apart():
    rows = fake_rows("window-size").head(3).assign(sensor_map=[None, '{"a": "b"}', ""])
    assert transferred(rows).tolist() == [False, True, False]


SHOWN = re.compile(r"([+-]\d+\.\d) \[([+-]\d+\.\d), ([+-]\d+\.\d)\] \(df ([\d.e+]+|∞)\)")


def parse(text: str) -> tuple[float, float, float, float]:
    found = SHOWN.fullmatch(text)
    assert found, text
    d, lo, hi, df = found.groups()
    return float(d), float(lo), float(hi), np.inf if df == "∞" else float(df)


def seeded(fingerprint: str, shift: float, seed_sd: float) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Two seeds per cell; the candidate's change moves by seed (retraining noise), so each
    dataset's interval rests on one seed degree of freedom."""
    base = fake_rows("window-size", "features", seeds=(0, 1)).head(24)
    base = base.assign(dataset_fingerprint=fingerprint)
    cand = shifted(base, "holweg", shift)
    by_seed = rng_for(0, "test-meta-seeds", fingerprint).normal(0, seed_sd, 2)
    return base, cand.assign(accuracy=cand["accuracy"] + by_seed[cand["seed"].to_numpy()])


def test_the_pooled_line_reproduces_from_the_shown_rows():
    """The issue's check: the pooled change, its interval, tau² and I² are what statsmodels and
    the stated method give from each dataset's change as the table prints it (estimate,
    interval, degrees of freedom), to the table's rounding; a dataset of two seeds enters with
    its own few degrees of freedom, not as if its standard error were known."""
    per = {"sim": seeded("sim", 0.02, 0.03), "dos": seeded("dos", 0.05, 0.01)}
    m = meta_analysis(per, ("features", "holweg"))
    table = summary_table([m])
    line = dict(zip(table.columns, table.cells[0]))
    shown = {name: parse(line[name]) for name in ("dos", "sim")}
    assert shown["sim"][3] < 5  # two seeds of a noisy retraining: few degrees of freedom
    d = np.array([x[0] for x in shown.values()]) / 100
    df = np.array([x[3] for x in shown.values()])
    se = np.array([(x[2] - x[1]) / 100 / (2 * student_t.ppf(0.975, x[3])) for x in shown.values()])
    res = combine_effects(d, se**2, method_re="iterated")
    w = 1 / (se**2 + res.tau2)
    within, between = w**2 * se**2 / w.sum() ** 2, res.tau2 * (w**2).sum() / w.sum() ** 2
    dof = (within.sum() + between) ** 2 / ((within**2 / df).sum() + between**2 / (len(d) - 1))
    half = student_t.ppf(0.975, dof) * np.sqrt(within.sum() + between)
    mean = (w * d).sum() / w.sum()
    pooled = parse(line["Pooled"])
    assert np.allclose(pooled[:3], 100 * np.array([mean, mean - half, mean + half]), atol=0.1)
    assert abs(float(line["tau² (points²)"]) - 1e4 * res.tau2) <= 0.01 + 0.05 * 1e4 * res.tau2
    # the normal pooling of the bootstrap's standard errors, as before, was narrower
    normal = 1.959964 / np.sqrt((1 / (m.datasets["se"] ** 2 + m.tau2)).sum())
    assert half > normal


def test_a_dataset_over_low_n_cells_carries_the_mark():
    base, cand = dataset("dos", 0.02)
    per = {"sim": dataset("sim", 0.04), "dos": (base.assign(low_n=True), cand)}
    table = summary_table([meta_analysis(per, ("features", "holweg"))])
    line = dict(zip(table.columns, table.cells[0]))
    assert line["dos"].endswith("†") and not line["sim"].endswith("†")
    assert any(
        f"dos: † {len(base)} of its paired cells rest on few test trials" in n for n in table.notes
    )


def test_a_cell_whose_interval_is_not_estimable_is_named_as_the_reason():
    """A cell that is not low n but whose class holds a single test trial (its row: no interval
    of accuracy, the note saying why) leaves its dataset out of the pooling; the reason says
    that, naming the cell, not "no standard error"."""
    base, cand = dataset("lab", 0.03)
    first = cand.index[0]
    cand.loc[first, ["accuracy_lo", "accuracy_hi"]] = np.nan
    cand["ci_note"] = ""
    cand.loc[first, "ci_note"] = (
        "accuracy, tp_rate: a class holds a single cluster, so nothing measures how its "
        "clusters vary; the interval given is the figure's whole range"
    )
    per = {"lab": (base, cand), "dos": dataset("dos", 0.02), "sim": dataset("sim", 0.04)}
    m = meta_analysis(per, ("features", "holweg"))
    reason = m.datasets.set_index("dataset").loc["lab", "reason"]
    cell = ", ".join(f"{k}={v}" for k, v in json.loads(cand.loc[first, "cell"]).items())
    assert reason == (
        "the interval of 1 cell is not estimable (a class holds a single test trial; the row "
        f"shows the figure's whole range): speed-holdout {cell}"
    )
    assert m.pooled_over == 2
    notes = " ".join(summary_table([m]).notes)
    assert f"holweg − features: lab left out: {reason}." in notes
    assert "no standard error" not in notes


def test_the_pooled_line_reads_its_interval_in_the_contrasts_words():
    """Differ on the pooled line: yes beyond the margin, no inside it, else undecided, read
    from the interval printed beside it."""
    from slipbench.stats.contrast import margin_of, state_of

    for shift, word in ((0.08, "yes"), (0.0, None)):
        per = {n: seeded(n, shift, 0.002) for n in ("sim", "dos", "lab")}
        m = meta_analysis(per, ("features", "holweg"))
        line = dict(zip(summary_table([m]).columns, summary_table([m]).cells[0]))
        expected = {"shown": "yes", "contradicted": "no", "undecided": "undecided"}[
            state_of(m.lo, m.hi, margin_of("accuracy"))
        ]
        assert line["Differ"] == expected
        if word:
            assert line["Differ"] == word and m.lo > 0.01
