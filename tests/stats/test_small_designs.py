"""Intervals on the small, clustered, mixed test sets labs have (issue 53): a lone pure trial
among mixed ones is resampled, and no interval is narrower than the binomial one of its windows.
The coverage on such designs is ``benchmarks/bench_coverage_small.py``'s
(``docs/studies/coverage.md``, "Small test sets")."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from slipbench.stats.bootstrap import Clusters, bell_mccaffrey_df, make_design
from slipbench.stats.metrics import FIGURES, RATES, binomial_floor, classification_figures
from slipbench.store.columns import EVERY_WINDOW, NONSLIP_WINDOWS, SLIP_WINDOWS

SHARED = Path(__file__).resolve().parents[3] / "shared"
HOLDSLIP = SHARED / "fixtures" / "small_holdslip.py"
XELA = SHARED / "datasets" / "xela-proactive" / "data_set"


def _lone_slip_among_mixed(n_mixed: int, n_hold: int, seed: int = 0):
    """``n_mixed`` trials holding both classes, one trial of slip alone, ``n_hold`` trials of
    hold alone; scores of the two classes overlapping."""
    rng = np.random.default_rng(seed)
    y, g = [], []
    for t in range(n_mixed):
        y += [0] * 20 + [1] * 20
        g += [t] * 40
    y += [1] * 20
    g += [n_mixed] * 20
    for t in range(n_hold):
        y += [0] * 30
        g += [n_mixed + 1 + t] * 30
    y, g = np.array(y, bool), np.array(g)
    scores = y + rng.normal(0, 0.6, len(y))
    return y, scores > 0.5, g, scores


@pytest.mark.parametrize(("n_mixed", "n_hold"), [(8, 7), (7, 0)])
def test_a_lone_pure_trial_among_mixed_ones_is_resampled(n_mixed, n_hold):
    """One trial of slip alone among trials of both classes: a class of one pure cluster made
    every figure drawing on it 'not estimable', [0, 100], while the row counted 8 slip trials."""
    y, pred, g, scores = _lone_slip_among_mixed(n_mixed, n_hold)
    design, _ = make_design([y], [g])
    assert not design.lone().any()
    out = classification_figures(y, pred, g, seed=0, scores=scores)
    assert "single cluster" not in out["ci_note"]
    assert out["n_test_clusters_slip"] == n_mixed + 1
    for name in FIGURES:
        lo, hi = out[f"{name}_lo"], out[f"{name}_hi"]
        assert np.isfinite([lo, hi]).all() and 0 < hi - lo < 0.5, (name, lo, hi)


def test_without_mixed_trials_a_class_of_one_trial_stays_not_estimable():
    """Nothing shares the class of a lone pure trial when no trial holds both classes: its
    figures keep the whole range, with the note."""
    y = np.array([1] * 10 + [0] * 30, bool)
    g = np.repeat([0, 1, 2, 3], 10)
    out = classification_figures(y, y.copy(), g, seed=0)
    assert "single cluster" in out["ci_note"]
    assert (out["tp_rate_lo"], out["tp_rate_hi"]) == (0.0, 1.0)


def test_few_trials_hold_the_binomial_interval_of_their_windows():
    """The issue's case: 8 of 10 windows right on 9 trials printed 80.0 [70.3, 87.1] (se 1.9
    points) beside a Wilson interval of [49.0, 94.3]: the two non-slip trials both missed their
    one window, so the stratified bootstrap saw no spread in the TN rate."""
    kinds = np.array([1, 0, 1, 0, 1, 1, 1, 1, 1], bool)
    g = np.array([0, 0, 1, 2, 3, 4, 5, 6, 7, 8])
    y = kinds[g]
    pred = y.copy()
    pred[[2, 4]] = ~pred[[2, 4]]
    out = classification_figures(y, pred, g, seed=0)
    assert out["accuracy"] == pytest.approx(0.8)
    for name in RATES:
        assert out[f"{name}_lo"] <= out[f"{name}_wilson_lo"] + 1e-12
        assert out[f"{name}_hi"] >= out[f"{name}_wilson_hi"] - 1e-12
    assert out["accuracy_lo"] < 0.5 and out["accuracy_se"] > 0.1
    assert "accuracy" in out["ci_note"] and "binomial" in out["ci_note"]


def test_the_balanced_accuracy_floor_is_the_binomial_variance_of_its_rates():
    """Equal rates on equal classes: the floor is Wilson's on every window; unequal classes
    take the windows whose binomial variance is the rates' mean's."""
    rates = {"tp_rate": 0.8, "tn_rate": 0.8, "accuracy": 0.8}
    even = {EVERY_WINDOW: 100, SLIP_WINDOWS: 50, NONSLIP_WINDOWS: 50}
    lo, hi, se = binomial_floor("balanced_accuracy", rates, even)
    wlo, whi, wse = binomial_floor("accuracy", rates, even)
    assert (lo, hi, se) == pytest.approx((wlo, whi, wse), abs=0.005)
    # 10 slip windows and 1000 non-slip ones: about 4 / (1/10 + 1/1000) = 40 windows' worth
    lopsided = {EVERY_WINDOW: 1010, SLIP_WINDOWS: 10, NONSLIP_WINDOWS: 1000}
    lo, hi, se = binomial_floor("balanced_accuracy", rates, lopsided)
    forty = binomial_floor("accuracy", rates, {EVERY_WINDOW: 40})
    assert (lo, hi) == pytest.approx(forty[:2], abs=0.02)
    assert binomial_floor("auroc", rates, lopsided) is None


def _no_whole_range_nor_narrow(rows: pd.DataFrame) -> None:
    """The issue's bar: no cell with >= 3 test trials of each class prints [0, 100] (at one
    decimal), nor an interval narrower than 0.8 x the Wilson interval of its windows."""
    checked = 0
    for _, row in rows.iterrows():
        for name in RATES:
            lo, hi = row[f"{name}_lo"], row[f"{name}_hi"]
            if not np.isfinite(row[name]):
                continue
            wide = row[f"{name}_wilson_hi"] - row[f"{name}_wilson_lo"]
            assert hi - lo >= 0.8 * wide - 1e-12, (row["cell"], name, lo, hi, wide)
        if min(row["n_test_clusters_slip"], row["n_test_clusters_nonslip"]) < 3:
            continue
        for name in FIGURES:
            lo, hi = row[f"{name}_lo"], row[f"{name}_hi"]
            if np.isfinite(row[name]):
                checked += 1
                assert not (round(100 * lo, 1) == 0 and round(100 * hi, 1) == 100), (
                    row["cell"],
                    name,
                    lo,
                    hi,
                    row["ci_note"],
                )
    assert checked > 0


def _evaluate(dataset_path: Path, out: Path) -> pd.DataFrame:
    from slipbench.data.read import read_dataset
    from slipbench.detectors.holweg import Holweg
    from slipbench.engine.runner import Run, evaluate
    from slipbench.protocols.window_size import WindowSize
    from slipbench.store.results import ResultsStore

    run = Run(Holweg(), WindowSize(), split="grouped", labels="majority")
    rows = evaluate(read_dataset(dataset_path), run, ResultsStore(out), jobs=0, progress=False)
    # windows longer than a 60 Hz recording allows are skipped, with their reason
    assert rows["status"].isin(["ok", "skipped"]).all() and (rows["status"] == "ok").any()
    return rows[rows["status"] == "ok"]


@pytest.mark.skipif(not HOLDSLIP.is_file(), reason=f"no fixture at {HOLDSLIP}")
def test_a_small_hold_slip_dataset_with_pure_trials(tmp_path):
    """The shared lab-shaped fixture: 8 hold-slip trials, one pure slip and one pure hold trial
    per unit, per-sample labels, a grouped split."""
    subprocess.run([sys.executable, str(HOLDSLIP), str(tmp_path / "ds")], check=True)
    _no_whole_range_nor_narrow(_evaluate(tmp_path / "ds", tmp_path / "res"))


def _xela(out: Path) -> Path:
    """The seven Xela trials as a slipbench dataset: two pads (one a finger), 48 taxel
    channels, per-sample slip labels."""
    from slipbench.data.write import write_dataset

    rows, samples, slip = [], {}, {}
    for folder in sorted(XELA.glob("data_sample_*")):
        rate = float(pd.read_csv(folder / "meta_data.csv")["frequency_hz"].iloc[0])
        labels = pd.read_csv(folder / "slip_label.csv")["slip"].to_numpy() > 0
        for pad in ("1", "2"):
            x = pd.read_csv(folder / f"xela_sensor{pad}.csv").to_numpy(np.float64)
            n = min(len(x), len(labels))
            rid = f"{folder.name}/pad{pad}"
            rows.append(
                dict(recording_id=rid, sensor_type="Xela", sensor_instance=f"pad{pad}",
                     scenario="hold-slip", material="box", speed_mm_s=np.nan,
                     sampling_rate_hz=rate, channels=tuple(f"c{i}" for i in range(x.shape[1])),
                     units=("count",) * x.shape[1], source="imanlab/proactive-slip-control",
                     trial=folder.name)
            )  # fmt: skip
            samples[rid], slip[rid] = x[:n], labels[:n]
    write_dataset(out, pd.DataFrame(rows), samples, slip)
    return out


@pytest.mark.skipif(not XELA.is_dir(), reason=f"Xela recordings not found at {XELA}")
def test_the_real_xela_trials(tmp_path):
    """Seven real trials, slip in short bursts within each: every interval holds 0.8 x its
    windows' Wilson width; a cell with 3 trials of each class is not the whole range."""
    rows = _evaluate(_xela(tmp_path / "xela"), tmp_path / "res")
    for _, row in rows.iterrows():
        for name in RATES:
            if np.isfinite(row[name]):
                wide = row[f"{name}_wilson_hi"] - row[f"{name}_wilson_lo"]
                assert row[f"{name}_hi"] - row[f"{name}_lo"] >= 0.8 * wide - 1e-12
    if (rows[["n_test_clusters_slip", "n_test_clusters_nonslip"]].min(axis=1) >= 3).any():
        _no_whole_range_nor_narrow(rows)


def test_design_degrees_of_freedom():
    """Bell-McCaffrey's degrees of freedom: clusters - 1 for equal clusters in one stratum, about
    the sum over strata for equal windows, and about the few-trial class's own where its windows
    weigh most (the balanced accuracy on 3 slip trials and 12 non-slip ones)."""
    y = np.repeat([True] * 3 + [False] * 12, 10)
    design, _ = make_design([y], [np.repeat(np.arange(15), 10)])
    every = np.ones(15, bool)
    # 2 + 11 by Satterthwaite: the strata's eigenvalues differ (3/2 x 10 and 12/11 x 10)
    assert bell_mccaffrey_df(Clusters(design, every, np.full(15, 10.0))) == pytest.approx(
        150**2 / (2 * 15**2 + 11 * (120 / 11) ** 2)
    )
    slip = np.arange(15) < 3
    assert bell_mccaffrey_df(Clusters(design, slip, np.full(15, 10.0))) == pytest.approx(2)
    weights = np.where(slip, 10 / (2 * 30) ** 2, 10 / (2 * 120) ** 2)
    df = bell_mccaffrey_df(Clusters(design, every, np.full(15, 10.0), weights))
    assert 2 < df < 3.5  # not the 12.8 of equal windows
    uneven = np.array([100.0, 5, 5] + [10] * 12)
    assert bell_mccaffrey_df(Clusters(design, slip, uneven)) < 2
