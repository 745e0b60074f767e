"""The conformance suite for plugins: ``check_detector(detector)`` and
``check_protocol(protocol)`` run every check and raise AssertionError naming the first that
fails; ``parametrize_with_checks([...])`` makes each check one pytest item. A third-party
plugin runs them in its own tests::

    from slipbench.testing import parametrize_with_checks

    @parametrize_with_checks([MyDetector(), MyProtocol()])
    def test_conformance(plugin, check):
        check(plugin)

A detector class may declare ``check_params``: hyperparameters that make these checks fast (few
epochs, few kernels); they are applied to a clone, never to the detector passed in. The checks
that fit run once per input kind the detector declares (its ``inputs``): on univariate windows
(n, window) and on windows of ``CHANNELS`` channels (n, window, CHANNELS), the latter named
``<Class>-<check>-channels``.
"""

from __future__ import annotations

from collections.abc import Callable

from slipbench.base import BaseDetector
from slipbench.data.toy import toy_windows
from slipbench.protocol import BaseProtocol
from slipbench.testing.data import CHANNELS, LENGTHS, toy, toy_channel_windows, toy_dataset
from slipbench.testing.detectors import (
    _fast,
    check_detector,
    check_fit_predict,
    check_input_kinds,
    check_params_protocol,
    check_refusals,
    check_save_load,
    check_streaming,
    check_uses_input,
    detector_checks,
)
from slipbench.testing.protocols import (
    PROTOCOL_CHECKS,
    check_protocol,
    check_protocol_cells,
    check_protocol_holdouts,
    check_protocol_layout,
    check_protocol_params,
)


def parametrize_with_checks(plugins: list) -> Callable:
    """A ``pytest.mark.parametrize`` decorator over (plugin, check): one test item per check of
    each detector or protocol, named ``<Class>-<check>``. The test calls ``check(plugin)``."""
    import pytest

    params = []
    checks: list[tuple[str, Callable[..., None], BaseDetector | BaseProtocol]]
    for plugin in plugins:
        if isinstance(plugin, BaseDetector):
            checks = [
                (name, check, plugin if check is check_params_protocol else _fast(plugin))
                for name, check in detector_checks(plugin)
            ]
        elif isinstance(plugin, BaseProtocol):
            checks = [(check.__name__, check, plugin) for check in PROTOCOL_CHECKS]
        else:
            raise TypeError(f"{plugin!r} is neither a BaseDetector nor a BaseProtocol")
        params += [
            pytest.param(obj, check, id=f"{type(plugin).__name__}-{name}")
            for name, check, obj in checks
        ]
    return pytest.mark.parametrize("plugin, check", params)


__all__ = [
    "CHANNELS",
    "LENGTHS",
    "PROTOCOL_CHECKS",
    "check_detector",
    "check_fit_predict",
    "check_input_kinds",
    "check_params_protocol",
    "check_protocol",
    "check_protocol_cells",
    "check_protocol_holdouts",
    "check_protocol_layout",
    "check_protocol_params",
    "check_refusals",
    "check_save_load",
    "check_streaming",
    "check_uses_input",
    "detector_checks",
    "parametrize_with_checks",
    "toy",
    "toy_channel_windows",
    "toy_dataset",
    "toy_windows",
]
