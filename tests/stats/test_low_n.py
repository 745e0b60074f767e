"""When a cell rests on few test trials: the classes a test set holds, a stream's trials and
onsets."""

from __future__ import annotations

import numpy as np

from slipbench.stats.metrics import classes_low_n, classification_figures, stream_low_n
from slipbench.vocabulary import LOW_N


def test_a_class_the_test_set_lacks_is_absent_not_few():
    assert not classes_low_n(1000, 0) and not classes_low_n(0, LOW_N)
    assert classes_low_n(LOW_N - 1, 0) and classes_low_n(0, 0)
    assert classes_low_n(50, LOW_N - 1) and not classes_low_n(LOW_N, LOW_N)
    y = np.ones(600, np.int8)  # a one-class test set: 60 trials of slip
    f = classification_figures(y, y, np.arange(600) // 10, seed=0)
    assert f["n_test_clusters_nonslip"] == 0 and not f["low_n"] and np.isnan(f["tn_rate"])


def test_a_stream_on_few_trials_or_onsets_is_low():
    assert stream_low_n(3, 40) and stream_low_n(40, 3) and stream_low_n(40, float("nan"))
    assert not stream_low_n(LOW_N, LOW_N)
