"""The conformance suite over every registered detector, and the suite catching broken ones."""

from __future__ import annotations

import numpy as np
import pytest

from slipbench.base import BaseDetector
from slipbench.registry import detectors
from slipbench.testing import check_detector


@pytest.mark.parametrize("name", detectors.names())
def test_registered_detector_conforms(name):
    check_detector(detectors.get(name)())


class _Nondeterministic(BaseDetector):
    name = "nondeterministic"

    def __init__(self, factor=1.0):
        self.factor = factor

    def _fit(self, x, y, seed):
        self.cut_ = float(np.random.default_rng().normal())  # ignores the seed

    def _predict_proba(self, x):
        return np.clip(x.mean(axis=1) * self.factor - self.cut_ + 0.5, 0, 1)


class _Renamer(_Nondeterministic):
    def __init__(self, factor=1.0):
        self.factor = factor * 2  # stores a parameter changed

    def _fit(self, x, y, seed):
        self.cut_ = 0.0


class _Unsaveable(_Renamer):
    def __init__(self, factor=1.0):
        self.factor = factor

    def _fit(self, x, y, seed):
        self.cut_, self.model_ = 0.0, object()


@pytest.mark.parametrize("cls, words", [(_Nondeterministic, "same scores"), (_Renamer, "clone must keep"),
                                        (_Unsaveable, "cannot save")])
def test_suite_catches_broken_detectors(cls, words):
    with pytest.raises((AssertionError, Exception), match=words):
        check_detector(cls())
