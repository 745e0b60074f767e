"""Every figure's rows and points from the coded history are figure_rows' and points' own."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from slipbench.history import coded, series


def _history(seed: int, runs: int = 30) -> pd.DataFrame:
    """Rows of two protocols, two detectors and some cells; repeated seeds in a run, results
    kept by a later run, missing figures, failed rows, missing pool settings and low n."""
    rng = np.random.default_rng(seed)
    rows = []
    for run in range(runs):
        for cell in range(12):
            for seed_ in range(1 + (run % 3 == 0)):
                kept = run > 0 and rng.random() < 0.1
                rows.append(
                    {
                        "run": run,
                        "series": f"{cell:016x}",
                        "series_label": f"label {cell}",
                        "key": f"k{run - kept}-{cell}-{seed_}",
                        "seed": int(rng.integers(0, 4)) * 10 + seed_,
                        "status": "ok" if rng.random() > 0.05 else "failed",
                        "low_n": bool(rng.random() < 0.05) if rng.random() > 0.1 else None,
                        "df": 30.0 if rng.random() > 0.1 else np.nan,
                        "protocol": ["window-size", "speed"][cell % 2],
                        "protocol_params": "{}" if cell % 5 else None,
                        "split": "grouped",
                        "labels": "scenario",
                        "detector": ["holweg", "bandpass"][cell % 3 == 0],
                        "accuracy": 0.8 + 0.01 * rng.standard_normal()
                        if rng.random() > 0.05
                        else None,
                        "accuracy_se": 0.01 * rng.random(),
                    }
                )
    return pd.DataFrame(rows)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rows_and_points_are_the_series_modules(seed):
    frame = _history(seed)
    want_rows = series.figure_rows(frame, "accuracy")
    got = coded.figure_rows(coded.Coded.of(frame), "accuracy")
    pd.testing.assert_frame_equal(got.frame(), want_rows, check_exact=True)
    want = series.points(want_rows)
    pts = coded.points(got)
    pts["kind"] = np.where(got.pooled[pts["series"]], "pooled", "cell")
    pts["series_label"] = got.labels[pts["series"]]
    pts["series"] = got.names[pts["series"]]
    pd.testing.assert_frame_equal(pts[want.columns], want, check_exact=True)
    assert (want["kind"] == "pooled").sum() > 0 and (want["n"] > 1).sum() > 0
