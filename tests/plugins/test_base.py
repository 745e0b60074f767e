"""The detector contract that the base class enforces for every plugin."""

from __future__ import annotations

import numpy as np
import pytest

from slipbench.base import BaseDetector, NotFittedError, clone
from slipbench.detectors.holweg import Holweg
from slipbench.errors import UsageError


def test_get_params_and_clone():
    det = Holweg(band=(0, 100), keep=0.5)
    assert det.get_params() == {"band": (0, 100), "keep": 0.5}
    copy = clone(det)
    assert copy is not det and copy.get_params() == det.get_params()
    with pytest.raises(UsageError, match="has no parameter 'nope'; its parameters: band, keep"):
        det.set_params(nope=1)


def test_input_is_checked_once_in_the_base_class():
    x = np.random.default_rng(0).normal(size=(20, 10)).astype(np.float32)
    y = np.r_[np.zeros(10), np.ones(10)].astype(int)
    with pytest.raises(NotFittedError):
        Holweg().predict(x)
    bad = x.copy()
    bad[3, 4] = np.nan
    with pytest.raises(UsageError, match="window 3, sample 4"):
        Holweg().fit(bad, y)
    with pytest.raises(UsageError, match="only class 1"):
        Holweg().fit(x, np.ones(20, int))
    with pytest.raises(UsageError, match="at least 5 samples"):
        Holweg().fit(x[:, :4], y)
    det = Holweg().fit(x, y)
    with pytest.raises(UsageError, match="fitted on windows of 10 samples, got 12"):
        det.predict(np.zeros((2, 12)))


def test_a_minimal_plugin_gets_the_contract_for_free():
    class Mean(BaseDetector):
        name = "mean"

        def __init__(self, offset=0.0):
            self.offset = offset

        def _fit(self, x, y, seed):
            self.cut_ = x.mean(axis=1)[y == 1].mean()

        def _predict_proba(self, x):
            return (x.mean(axis=1) + self.offset > self.cut_).astype(float)

    x = np.r_[np.zeros((5, 6)), np.ones((5, 6))]
    det = Mean(offset=0.1).fit(x, np.r_[np.zeros(5), np.ones(5)].astype(int))
    assert det.predict(x).tolist() == [0] * 5 + [1] * 5
    assert det.sampling_rate_ == 1000.0 and det.window_length_ == 6
