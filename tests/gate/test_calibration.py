"""A bench's calibration: the seed and paired variances it measures from a run and its retrained
twin (checked on rows built with known noise, and by simulation), the file it is kept in, and
when it no longer holds."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from slipbench.errors import DataError
from slipbench.gate.calibration import (
    CALIBRATION,
    Calibration,
    DetectorCalibration,
    calibration_path,
    deterministic,
    measure,
    read_calibration,
    stale_reasons,
)
from slipbench.stats.noise import SeedNoise

FIGURES = ["accuracy", "tn_rate"]


def _rows(seeds=6, cells=3, seed_sd=0.02, retrain_sd=0.01, rng=None, offset=None):
    """Rows of one detector on one protocol: a figure is 0.8 + the seed's luck (its split,
    shared by the cells, and by the twin) + the training's luck of each cell (the run's and
    the twin's their own)."""
    rng = rng or np.random.default_rng(0)
    luck = offset if offset is not None else rng.normal(0, seed_sd, seeds)
    out = []
    for s in range(seeds):
        for c in range(cells):
            value = 0.8 + 0.01 * c + luck[s] + rng.normal(0, retrain_sd)
            out.append(
                {
                    "detector": "d",
                    "protocol": "p",
                    "cell": f'{{"window": {c}}}',
                    "seed": s,
                    "status": "ok",
                    "accuracy": value,
                    "accuracy_se": 0.02,
                    "tn_rate": value - 0.05,
                    "tn_rate_se": 0.03,
                }
            )
    return pd.DataFrame(out)


def _pair(**kw):
    rng = np.random.default_rng(kw.pop("seed", 0))
    luck = rng.normal(0, kw.get("seed_sd", 0.02), kw.get("seeds", 6))
    return _rows(rng=rng, offset=luck, **kw), _rows(rng=rng, offset=luck, **kw)


def test_measure_gives_each_variance_with_its_degrees_of_freedom():
    runs, twins = _pair()
    part = measure(runs, twins, FIGURES)["d"]["p"]
    assert set(part.cells) == {f'{{"window": {c}}}' for c in range(3)}
    mean_run = runs.groupby("seed")["accuracy"].mean()
    mean_twin = twins.groupby("seed")["accuracy"].mean()
    noise = part.figures["accuracy"]
    assert noise.seeds == 6 and noise.cells == 3 and noise.seed_df == 5 and noise.paired_df == 6
    assert noise.mean == pytest.approx(mean_run.mean())
    assert noise.seed_var == pytest.approx(mean_run.var(ddof=1))
    assert noise.paired_var == pytest.approx(((mean_twin - mean_run) ** 2).mean())
    assert noise.trial_var == pytest.approx(0.02**2)
    cell = part.cells['{"window": 1}']["tn_rate"]
    one = runs[runs["cell"] == '{"window": 1}'].set_index("seed")["tn_rate"]
    assert cell.seed_var == pytest.approx(one.var(ddof=1))
    # same seeds: the twin's noise and the test trials' share of the drop asked for (a
    # 3-point drop flips at least 3 % of the windows: 0.03 / (p (1 - p)) of the trials' variance)
    share = 0.03 / (noise.mean * (1 - noise.mean))
    assert noise.per_seed(paired=True, drop=0.03) == pytest.approx(
        noise.paired_var + share * noise.trial_var
    )
    assert noise.per_seed(paired=True) == pytest.approx(noise.paired_var + noise.trial_var)
    assert noise.per_seed(paired=False) == 2 * noise.seed_var
    assert noise.pool(paired=True) == SeedNoise(noise.paired_var, 6.0, CALIBRATION)
    assert noise.pool(paired=False) == SeedNoise(noise.seed_var, 5.0, CALIBRATION)


def test_cells_that_did_not_finish_every_seed_or_lack_a_figure_are_left_out():
    runs, twins = _pair()
    runs.loc[(runs["cell"] == '{"window": 0}') & (runs["seed"] == 2), "status"] = "failed"
    twins.loc[twins["cell"] == '{"window": 1}', "tn_rate"] = np.nan  # one class: no TN rate
    part = measure(runs, twins, FIGURES)["d"]["p"]
    assert set(part.cells) == {'{"window": 1}', '{"window": 2}'}
    assert set(part.cells['{"window": 1}']) == {"accuracy"}
    assert part.figures["accuracy"].cells == 2 and part.figures["tn_rate"].cells == 1
    kept = runs[runs["cell"] == '{"window": 2}'].set_index("seed")["tn_rate"]
    assert part.figures["tn_rate"].seed_var == pytest.approx(kept.var(ddof=1))


def test_the_paired_variance_is_unbiased_for_the_twins_difference():
    """Over simulated calibrations, paired_var averages the variance of one seed's twin - run
    difference of the protocol's mean (2 retrain_sd^2 / cells: the split's luck cancels), and
    seed_var the variance of one seed's mean (seed_sd^2 + retrain_sd^2 / cells): unbiased."""
    paired, apart = [], []
    for rep in range(20):  # 60 seeds each: the means' relative error is about 4 %
        runs, twins = _pair(seed=rep, seeds=60, seed_sd=0.03, retrain_sd=0.01)
        noise = measure(runs, twins, ["accuracy"])["d"]["p"].figures["accuracy"]
        paired.append(noise.paired_var)
        apart.append(noise.seed_var)
    assert np.mean(paired) == pytest.approx(2 * 0.01**2 / 3, rel=0.12)
    assert np.mean(apart) == pytest.approx(0.03**2 + 0.01**2 / 3, rel=0.12)


def test_a_twin_equal_to_its_run_is_deterministic():
    runs, _ = _pair()
    assert deterministic(runs, runs.copy(), FIGURES)
    off = runs.copy()
    off.loc[5, "accuracy"] += 1e-6
    assert not deterministic(runs, off, FIGURES)
    both_nan = runs.copy()
    both_nan["tn_rate"] = np.nan
    assert deterministic(both_nan, both_nan.copy(), FIGURES)
    assert measure(runs, runs.copy(), FIGURES)["d"]["p"].figures["accuracy"].paired_var == 0


def _calibration(digest="abc", params=None, code="src:1"):
    runs, twins = _pair()
    return Calibration(
        settings={"split": "grouped"},
        digest=digest,
        seeds=tuple(range(6)),
        dataset_fingerprint="f" * 16,
        created="2026-01-01T00:00:00+00:00",
        slipbench_version="0.1",
        wall_seconds_per_seed=12.5,
        machine={"processors": 2, "jobs": 2},
        detectors={
            "d": DetectorCalibration(
                params=params if params is not None else {"keep": 0.8},
                code=code,
                deterministic=False,
                seconds_per_seed=float("nan"),
                protocols=measure(runs, twins, FIGURES)["d"],
            )
        },
    )


def test_the_file_round_trips_and_holds_no_nan(tmp_path):
    cal = _calibration()
    path = tmp_path / "bench.calibration.json"
    path.write_text(cal.to_json())
    assert "NaN" not in path.read_text()  # strict JSON: NaN as null
    back = read_calibration(path)
    assert back.to_json() == cal.to_json()
    assert math.isnan(back.detectors["d"].seconds_per_seed)
    assert back.noise("d", "p", "accuracy") == cal.noise("d", "p", "accuracy")
    assert back.noise("d", "p", "tn_rate", '{"window": 2}') is not None
    assert back.noise("d", "q", "accuracy") is None and back.noise("x", "p", "accuracy") is None
    assert calibration_path(tmp_path / "bench.toml") == path


@pytest.mark.parametrize(
    "text, says",
    [
        ("{not json", "not JSON"),
        ('{"format": "other"}', "not a slipbench calibration"),
        ('{"format": "slipbench-calibration", "version": 99}', "format version 99"),
        ('{"format": "slipbench-calibration", "version": 1}', "missing or malformed"),
    ],
)
def test_a_file_that_is_not_a_calibration_is_refused_naming_it(tmp_path, text, says):
    path = tmp_path / "bench.calibration.json"
    path.write_text(text)
    with pytest.raises(DataError, match=says) as caught:
        read_calibration(path)
    assert str(path) in str(caught.value) and "slipbench calibrate" in str(caught.value)


def test_a_malformed_number_is_refused(tmp_path):
    data = json.loads(_calibration().to_json())
    data["wall_seconds_per_seed"] = "fast"
    path = tmp_path / "x.json"
    path.write_text(json.dumps(data))
    with pytest.raises(DataError, match="expected a number"):
        read_calibration(path)


def test_stale_names_each_detector_it_no_longer_holds_for():
    cal = _calibration()
    assert stale_reasons(cal, "abc", {"d": ({"keep": 0.8}, "src:1")}) == {}
    assert stale_reasons(cal, "abc", {"d": ({"keep": 0.80}, "src:1")}) == {}  # 0.8 == 0.80
    assert "settings" in stale_reasons(cal, "xyz", {"d": ({"keep": 0.8}, "src:1")})["d"]
    assert "parameters" in stale_reasons(cal, "abc", {"d": ({"keep": 0.7}, "src:1")})["d"]
    assert "code" in stale_reasons(cal, "abc", {"d": ({"keep": 0.8}, "src:2")})["d"]
    assert "not calibrated" in stale_reasons(cal, "abc", {"e": ({}, "src:1")})["e"]
