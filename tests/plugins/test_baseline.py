"""The reference baseline `features`: its statistics, its reading of real labs' data, and its
mark as the reference in the contract and in `slipbench list`."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from sklearn.exceptions import ConvergenceWarning

from slipbench.detectors.features import STATISTICS, Features, octave_matrix
from slipbench.engine.registry import detectors
from slipbench.testing import toy_channel_windows, toy_windows

SOURCE = Path(__file__).resolve().parents[3] / "shared" / "datasets" / "biotacsp-dos" / "csvs"


@pytest.mark.parametrize(
    "length, bins",
    [
        (5, [[2], [1]]),  # 400 Hz and 200 Hz of 500: two octaves hold a bin, two are dropped
        (50, [list(range(13, 26)), list(range(7, 13)), [4, 5, 6], [1, 2, 3]]),
    ],
)
def test_octaves_average_the_bins_below_nyquist_top_first(length, bins):
    weights = octave_matrix(length, 4)
    assert weights.shape == (length // 2 + 1, len(bins))
    assert [np.flatnonzero(w).tolist() for w in weights.T] == bins
    np.testing.assert_allclose(weights.sum(axis=0), 1.0)
    assert (weights[0] == 0).all()  # DC is the mean, a statistic of its own


def test_each_channel_gets_the_statistics_of_its_own_signal_and_channels_are_learnt():
    x, y = toy_channel_windows(400, 50, channels=4)  # slip: a burst in channel 0 only
    det = Features().fit(x[:200], y[:200], seed=0)
    per_channel = len(STATISTICS) + det.octaves_.shape[1]
    assert det.coef_.shape == (4 * per_channel,)
    assert (det.predict(x[200:]) == y[200:]).mean() > 0.9
    each = det._statistics(x[:10])
    for c in range(4):
        np.testing.assert_allclose(
            each[:, c * per_channel : (c + 1) * per_channel],
            det._statistics(np.ascontiguousarray(x[:10, :, c])),
        )


def test_integer_counts_of_any_unit_score_as_their_standardized_twin():
    """A lab's raw ADC counts: a million times the scale, rounded, and 24 channels at 100 Hz."""
    x, y = toy_channel_windows(300, 50, channels=24)
    counts = np.round(x * 1e6).astype(np.int64)
    scaled = Features().fit(counts, y, sampling_rate=100.0).predict_proba(counts)
    plain = Features().fit(counts / 1e6, y, sampling_rate=100.0).predict_proba(counts / 1e6)
    np.testing.assert_allclose(scaled, plain, atol=1e-6)
    still = np.zeros_like(x[:3])  # a window where nothing moves stays finite
    assert np.isfinite(Features().fit(x, y).predict_proba(still)).all()


def test_the_univariate_signal_is_learnt_and_the_fit_says_it_converged():
    x, y = toy_windows(400, 50)  # slip adds a 60 Hz burst
    det = Features().fit(x[:200], y[:200], seed=0)
    assert (det.predict(x[200:]) == y[200:]).mean() > 0.9
    assert det.fitted_choices() == {"iterations": det.iterations_, "converged": True}
    with pytest.warns(ConvergenceWarning):
        stopped = Features(max_iter=10, C=1e6).fit(x[:200], y[:200])
    assert stopped.fitted_choices()["converged"] is False


def test_one_registered_detector_is_the_reference_and_list_says_so(cli):
    marked = [n for n in detectors.names() if detectors.get(n).reference]
    assert marked == ["features"]
    code, text, _ = cli(["list"])
    entry = text.split("\n  features", 1)[1].split("\n  holweg", 1)[0]
    assert code == 0 and "the baseline every table will compare against" in entry
    code, text, _ = cli(["list", "--json"])
    found = {e["name"]: e for e in json.loads(text)["detectors"]}
    assert found["features"]["reference"] is True and found["holweg"]["reference"] is False
    assert "reference" not in json.loads(text)["protocols"][0]


@pytest.mark.slow
@pytest.mark.skipif(not SOURCE.is_dir(), reason=f"BioTacSP-DoS not found at {SOURCE}")
def test_dos_channels_and_signal_at_500_ms_with_the_grouped_split(tmp_path, cli):
    """24 electrodes at 100 Hz, no speeds, touch outnumbered 6 to 1: both inputs run."""
    code, _, err = cli(["dataset", "import", "biotacsp-dos", str(SOURCE), str(tmp_path / "dos")])
    assert code == 0, err
    argv = ["evaluate", "--detector", "features", "--protocol", "window-size", "--quiet"]
    argv += ["--dataset", str(tmp_path / "dos"), "--out", str(tmp_path / "out")]
    argv += ["--protocol-param", 'windows=["500ms"]', "--split", "grouped", "--input", "both"]
    code, _, err = cli(argv)
    assert code == 0, err
    rows = pd.read_parquet(tmp_path / "out" / "results.parquet").set_index("input")
    assert (rows["status"] == "ok").all() and rows.loc["channels", "window"] == 50
    # seed 0's split; benchmarks/bench_baseline.py gives the figures over five seeds
    assert rows.loc["channels", "balanced_accuracy"] > 0.8
    assert rows.loc["univariate", "balanced_accuracy"] > 0.65
