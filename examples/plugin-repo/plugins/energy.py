"""The example detector of the README and the plugins guide: mean absolute signal above a
training quantile."""

import numpy as np

from slipbench.base import BaseDetector
from slipbench.params import Interval


class Energy(BaseDetector):
    """Mean absolute signal above a training quantile."""

    _parameter_constraints = {"quantile": Interval(float, 0.0, 1.0)}

    def __init__(self, quantile=0.5):
        self.quantile = quantile

    def _fit(self, x, y, seed):  # x: (n_windows, window_length) float32; y: 0/1 int8
        self.cut_ = float(np.quantile(np.abs(x).mean(axis=1), self.quantile))

    def _predict_proba(self, x):  # -> (n_windows,) probabilities of slip in [0, 1]
        return (np.abs(x).mean(axis=1) > self.cut_).astype(float)
