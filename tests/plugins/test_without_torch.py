"""The plain install has no torch: the LSTM runs on its numba kernels, what needs torch (its GPU
path, its speed reference, the tcn detector) says what to install."""

from __future__ import annotations

import importlib.util
import sys

import numpy as np
import pytest

from slipbench.engine.registry import detectors
from slipbench.errors import UsageError
from slipbench.testing import toy_windows

LSTM = detectors.get("lstm")


@pytest.fixture
def no_torch(monkeypatch):
    """torch as if it were not installed: its import fails and its spec is not found."""
    monkeypatch.setitem(sys.modules, "torch", None)
    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "torch" else real(name, *a)
    )


def test_auto_device_trains_and_predicts_on_the_cpu(no_torch):
    x, y = toy_windows(n=60, length=20, seed=0)
    det = LSTM(max_epochs=2, hidden_size=4).fit(x, y, seed=0)
    p = det.predict_proba(x)
    assert p.shape == (len(x),) and np.all((p >= 0) & (p <= 1))


def test_cuda_device_is_refused_with_the_install_command(no_torch):
    with pytest.raises(UsageError, match=r"torch is not installed.*slipbench\[torch\]"):
        LSTM(device="cuda").validate_params()


def test_speed_reference_is_skipped_with_one_warning(no_torch):
    with pytest.warns(UserWarning, match=r"torch is not installed.*slipbench\[torch\]"):
        assert LSTM.benchmark(length=20, seconds=0.01) is None


def test_tcn_is_unavailable_and_refused_with_the_install_command(no_torch, cli):
    status = detectors.status("tcn")
    assert status.state == "unavailable" and "slipbench[torch]" in status.detail
    code, _, err = cli(["evaluate", "--detector", "tcn", "--protocol", "window-size"])
    assert code == 3 and "slipbench[torch]" in err and "Traceback" not in err
